#include "libs/mdns/txt_list.hpp"

#include <avahi-common/malloc.h>

namespace rcand::mdns {

TxtList to_txt_list(const std::map<std::string, std::string>& txt) {
  AvahiStringList* list = nullptr;
  for (const auto& [key, value] : txt) list = avahi_string_list_add_pair(list, key.c_str(), value.c_str());
  return TxtList(avahi_string_list_reverse(list));  // keep the map's order on the wire
}

std::map<std::string, std::string> from_txt_list(AvahiStringList* list) {
  std::map<std::string, std::string> txt;
  for (AvahiStringList* item = list; item != nullptr; item = avahi_string_list_get_next(item)) {
    char* key = nullptr;
    char* value = nullptr;
    if (avahi_string_list_get_pair(item, &key, &value, nullptr) != 0) continue;
    txt[key] = value != nullptr ? value : "";
    avahi_free(key);
    avahi_free(value);
  }
  return txt;
}

}  // namespace rcand::mdns
