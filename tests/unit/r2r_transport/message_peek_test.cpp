#include <doctest/doctest.h>

#include <string>
#include <vector>

#include "services/r2r/transports/message_peek.hpp"

using rcand::services::r2r::peek_message;

TEST_CASE("peek finds the type and header.source_id wherever they are written") {
  auto peek = peek_message(R"({"header":{"version":"1.0","auth":{"token":"x"},"source_id":"bot-a"},"payload":{"type":"no",
                               "header":{"source_id":"inner"}},"type":"status"})");
  CHECK(peek.type == "status");
  CHECK(peek.source_id == "bot-a");
  peek = peek_message(R"({"type":"command","payload":{},"header":{"source_id":"b"}})");
  CHECK(peek.type == "command");
  CHECK(peek.source_id == "b");
}

TEST_CASE("peek leaves the fields empty for anything odd, and never throws") {
  for (const std::string& bad :
       std::vector<std::string>{"", "not json", "[1,2,3]", R"({"type":5,"header":{"source_id":[]}})", R"({"type":"st)",
                                std::string(100000, '['), R"({"header":"x","type":null})"}) {
    const auto peek = peek_message(bad);
    CHECK(peek.type.empty());
    CHECK(peek.source_id.empty());
  }
  // A truncated message still yields what came before the cut.
  CHECK(peek_message(R"({"type":"status","header":{"source_id":"a")").source_id == "a");
}

TEST_CASE("peek tells a relayed message (header.relayed_by) from the sender's own, wherever the marker is written") {
  CHECK_FALSE(peek_message(R"({"header":{"source_id":"c"},"type":"status","payload":{"relayed_by":"x"}})").relayed);
  CHECK(peek_message(R"({"type":"command","header":{"source_id":"c","relayed_by":"alex"},"payload":{}})").relayed);
  CHECK(peek_message(R"({"header":{"relayed_by":"alex","source_id":"c"},"type":"command"})").relayed);
}
