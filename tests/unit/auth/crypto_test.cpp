#include <doctest/doctest.h>

#include <set>
#include <string>

#include "libs/rcan/crypto.hpp"

using namespace rcand;

namespace {
std::string hex(const std::string& raw) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  for (unsigned char c : raw) {
    out.push_back(kDigits[c >> 4]);
    out.push_back(kDigits[c & 15]);
  }
  return out;
}
}  // namespace

TEST_CASE("sha256_hex matches FIPS 180-2 vectors") {
  CHECK(sha256_hex("") == "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  CHECK(sha256_hex("abc") == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

TEST_CASE("hmac_sha256 matches RFC 4231") {
  SUBCASE("test case 1") {
    CHECK(hex(hmac_sha256(std::string(20, '\x0b'), "Hi There")) ==
          "b0344c61d8db38535ca8afceaf0bf12b881dc200c9833da726e9376c2e32cff7");
  }
  SUBCASE("test case 2: short key") {
    CHECK(hex(hmac_sha256("Jefe", "what do ya want for nothing?")) ==
          "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843");
  }
  SUBCASE("test case 6: key longer than the block") {
    CHECK(hex(hmac_sha256(std::string(131, '\xaa'), "Test Using Larger Than Block-Size Key - Hash Key First")) ==
          "60e431591ee0b67f0d8a26aacbf5b77f8e0bc6213728c5140546040f0ee37f54");
  }
  SUBCASE("empty key still works and is 32 bytes") {
    const std::string tag = hmac_sha256("", "data");
    CHECK(tag.size() == 32);
    CHECK(tag != hmac_sha256("k", "data"));
  }
}

TEST_CASE("base64url_encode: RFC 4648 vectors without padding, url alphabet") {
  CHECK(base64url_encode("") == "");
  CHECK(base64url_encode("f") == "Zg");
  CHECK(base64url_encode("fo") == "Zm8");
  CHECK(base64url_encode("foo") == "Zm9v");
  CHECK(base64url_encode("foob") == "Zm9vYg");
  CHECK(base64url_encode("fooba") == "Zm9vYmE");
  CHECK(base64url_encode("foobar") == "Zm9vYmFy");
  CHECK(base64url_encode("\xfb\xff") == "-_8");
  CHECK(base64url_encode(std::string("\0\0\0", 3)) == "AAAA");
}

TEST_CASE("base64url_decode round-trips and rejects bad input") {
  for (const std::string s : {"", "f", "fo", "foo", "foob", "fooba", "foobar", "\xfb\xff\xfe", "a\0b"}) {
    const auto decoded = base64url_decode(base64url_encode(s));
    REQUIRE(decoded);
    CHECK(*decoded == s);
  }
  std::string all;
  for (int i = 0; i < 256; ++i) all.push_back(static_cast<char>(i));
  CHECK(base64url_decode(base64url_encode(all)) == all);

  CHECK(base64url_decode("-_8") == std::string("\xfb\xff"));
  CHECK_FALSE(base64url_decode("Zg=="));   // padding
  CHECK_FALSE(base64url_decode("Zg="));
  CHECK_FALSE(base64url_decode("Z"));      // 4n+1 characters
  CHECK_FALSE(base64url_decode("Zm9vY"));
  CHECK_FALSE(base64url_decode("+/8"));    // standard alphabet
  CHECK_FALSE(base64url_decode("Zm 9v"));  // whitespace
  CHECK_FALSE(base64url_decode("Zm9v\n"));
  CHECK_FALSE(base64url_decode("Zh"));     // non-canonical trailing bits ("f" is "Zg")
  CHECK_FALSE(base64url_decode("Zm9"));    // "fo" is "Zm8"
  CHECK_FALSE(base64url_decode(std::string("Zg\0", 3)));
  CHECK_FALSE(base64url_decode("Zm9v.Zg"));
}

TEST_CASE("constant_time_equals") {
  CHECK(constant_time_equals("", ""));
  CHECK(constant_time_equals("abc", "abc"));
  CHECK_FALSE(constant_time_equals("abc", "abd"));
  CHECK_FALSE(constant_time_equals("abc", "ab"));
  CHECK_FALSE(constant_time_equals("", "a"));
  CHECK(constant_time_equals(std::string("a\0b", 3), std::string("a\0b", 3)));
  CHECK_FALSE(constant_time_equals(std::string("a\0b", 3), std::string("a\0c", 3)));
}

TEST_CASE("random_hex gives lowercase hex of the requested size, different every time") {
  std::set<std::string> seen;
  for (int i = 0; i < 20; ++i) {
    const std::string value = random_hex(32);
    CHECK(value.size() == 64);
    CHECK(value.find_first_not_of("0123456789abcdef") == std::string::npos);
    seen.insert(value);
  }
  CHECK(seen.size() == 20);
  CHECK(random_hex(0).empty());
}
