// A valid library that exports no entry symbol at all (hidden visibility, no RCAND_PLUGIN).
int rcand_test_no_entry_internal() { return 42; }
