// libFuzzer target: a plugin manifest from bytes, as the plugin host reads one (JSON, then parse_manifest).
// Invalid JSON is the loader's ManifestError and is skipped here; from a JSON document only ManifestError may
// escape, and an accepted manifest has an id, a library inside its folder's tree, and only known kinds.
#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>

#include "fuzz_check.hpp"
#include "libs/manifest/manifest.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto doc = nlohmann::json::parse(data, data + size, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return 0;
  try {
    const auto manifest = rcand::parse_manifest(doc, "/fuzz/plugins/plugin.json");
    RCAND_FUZZ_CHECK(!manifest.id.empty(), "an accepted manifest has an id");
    RCAND_FUZZ_CHECK(manifest.library.is_absolute(), "the library path is resolved");
    for (const auto& item : manifest.provides)
      RCAND_FUZZ_CHECK(item.kind == "capability" || item.kind == "driver", "provides only capabilities and drivers");
  } catch (const rcand::ManifestError& error) {
    RCAND_FUZZ_CHECK(std::string_view(error.what()).find("/fuzz/plugins/plugin.json") != std::string_view::npos,
                     "a manifest error names the file");
  }
  return 0;
}
