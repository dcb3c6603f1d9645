#include "libs/rcan/loopback.hpp"

#include <boost/asio/ip/address.hpp>

namespace rcand {

bool is_loopback_address(const std::string& address) {
  boost::system::error_code ec;
  const auto parsed = boost::asio::ip::make_address(address, ec);
  if (ec) return false;  // names ("localhost") too: the server binds literal addresses only
  if (parsed.is_v6() && parsed.to_v6().is_v4_mapped())
    return boost::asio::ip::make_address_v4(boost::asio::ip::v4_mapped, parsed.to_v6()).is_loopback();
  return parsed.is_loopback();
}

}  // namespace rcand
