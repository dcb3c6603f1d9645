#include "services/r2r/transports/message_peek.hpp"

#include <nlohmann/json.hpp>

#include <vector>

#include "libs/r2r_wire/envelope.hpp"

namespace rcand::services::r2r {
namespace {

// SAX handler: records top-level "type" and "header"."source_id" strings and whether the header carries the hop
// marker, and stops once both strings are known and the header has been read to its end.
class PeekHandler : public nlohmann::json_sax<nlohmann::json> {
 public:
  explicit PeekHandler(MessagePeek& out) : out_(out) {}

  bool null() override { return true; }
  bool boolean(bool) override { return true; }
  bool number_integer(number_integer_t) override { return true; }
  bool number_unsigned(number_unsigned_t) override { return true; }
  bool number_float(number_float_t, const string_t&) override { return true; }
  bool binary(binary_t&) override { return true; }
  bool string(string_t& value) override {
    if (stack_.size() == 1 && stack_[0].is_object && stack_[0].key == "type") out_.type = value;
    if (stack_.size() == 2 && stack_[0].is_object && stack_[0].key == "header" && stack_[1].is_object &&
        stack_[1].key == "source_id")
      out_.source_id = value;
    return !complete();  // false stops the scan
  }
  bool start_object(std::size_t) override { return push(true); }
  bool end_object() override {
    if (in_header()) header_done_ = true;
    return pop() && !complete();
  }
  bool start_array(std::size_t) override { return push(false); }
  bool end_array() override { return pop(); }
  bool key(string_t& value) override {
    if (in_header() && value == r2r_wire::kRelayMarker) out_.relayed = true;
    if (!stack_.empty()) stack_.back().key = value;
    return true;
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override { return false; }

 private:
  struct Frame {
    bool is_object = false;
    std::string key;
  };
  static constexpr std::size_t kMaxDepth = 64;
  bool push(bool is_object) {
    stack_.push_back({is_object, {}});
    return stack_.size() <= kMaxDepth;
  }
  bool pop() {
    if (!stack_.empty()) stack_.pop_back();
    return true;
  }

  bool in_header() const { return stack_.size() == 2 && stack_[0].is_object && stack_[0].key == "header" && stack_[1].is_object; }
  // Everything to learn is known: the type, the source, and the whole header (a hop marker may follow source_id).
  bool complete() const { return !out_.type.empty() && !out_.source_id.empty() && header_done_; }

  MessagePeek& out_;
  std::vector<Frame> stack_;
  bool header_done_ = false;
};

}  // namespace

MessagePeek peek_message(std::string_view bytes) noexcept {
  MessagePeek out;
  try {
    PeekHandler handler(out);
    nlohmann::json::sax_parse(bytes.begin(), bytes.end(), &handler, nlohmann::json::input_format_t::json, false);
  } catch (...) {  // never: sax_parse with strict=false and a handler that returns false does not throw; be safe
  }
  return out;
}

}  // namespace rcand::services::r2r
