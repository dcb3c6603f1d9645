// The kernel's, the services' and rcanctl's name for the SDK's bounded_text (rcand/sdk/bounded_text.hpp): one helper
// for every piece of untrusted text quoted back or logged, the same one plugins call.
#pragma once

#include <rcand/sdk/bounded_text.hpp>

namespace rcand {

using sdk::bounded_text;
using sdk::kQuotedTextLimit;

}  // namespace rcand
