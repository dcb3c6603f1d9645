// A service interface of the fixtures' own, as a vendor would define one: both fixture plugins include this header;
// rcand knows nothing of it and matches its id only.
#pragma once

#include <rcand/sdk/export.hpp>
#include <rcand/sdk/services.hpp>

#include <string_view>

namespace rcand::test {

class RCAND_INTERFACE Greeter {
 public:
  static constexpr std::string_view kServiceId = "org.rcand.test.greeter/1";
  virtual ~Greeter() = default;
  virtual const char* greeting() const noexcept = 0;
};

}  // namespace rcand::test
