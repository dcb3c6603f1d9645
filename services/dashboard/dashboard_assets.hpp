// The dashboard's static files, embedded at build time (embed_assets.cmake).
#pragma once

#include <string>
#include <vector>

namespace rcand::services::dashboard {

struct Asset {
  std::string name;          // "index.html", "app.js"
  std::string content_type;  // with charset for text
  std::string body;
};

const std::vector<Asset>& assets();

}  // namespace rcand::services::dashboard
