// TXT records between rcand's map and Avahi's string lists (RAII for the list).
#pragma once

#include <avahi-common/strlst.h>

#include <map>
#include <memory>
#include <string>

namespace rcand::mdns {

struct TxtListFree {
  void operator()(AvahiStringList* list) const noexcept { avahi_string_list_free(list); }
};
using TxtList = std::unique_ptr<AvahiStringList, TxtListFree>;

// "key=value" entries; an empty map is an empty (null) list.
TxtList to_txt_list(const std::map<std::string, std::string>& txt);
// Entries without '=' become keys with an empty value (RFC 6763 §6.4 boolean attributes).
std::map<std::string, std::string> from_txt_list(AvahiStringList* list);

}  // namespace rcand::mdns
