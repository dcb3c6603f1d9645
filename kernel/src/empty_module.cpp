// Placeholder translation unit for a kernel module that has no sources yet (removed once all modules exist).
