// The busy lane's eviction rule (libs/http/busy_lane): which waiter makes room, and that a stop is never the one.
#include <doctest/doctest.h>

#include <vector>

#include "libs/http/busy_lane.hpp"

using rcand::http::Request;
using namespace rcand::http::detail;

namespace {

bool is_stop(const Request& request) { return request.method == "POST" && request.path == "/api/stop"; }

PendingInput classify(std::string_view bytes) { return classify_pending(bytes, is_stop); }

}  // namespace

TEST_CASE("what a waiter has sent is classified by its request line") {
  CHECK(classify("") == PendingInput::Silent);
  CHECK(classify("POST /api/stop HTTP/1.1\r\nHost: h\r\n") == PendingInput::Priority);
  CHECK(classify("POST /api/stop?token=x HTTP/1.1") == PendingInput::Priority);  // the path, not the target
  CHECK(classify("POST /api/stop ") == PendingInput::Priority);                  // the line's end may still come
  CHECK(classify("GET /api/status HTTP/1.1\r\n") == PendingInput::Ordinary);
  CHECK(classify("POST /api/stopper HTTP/1.1\r\n") == PendingInput::Ordinary);
  CHECK(classify("POST /api/sto") == PendingInput::Partial);
  CHECK(classify("P") == PendingInput::Partial);
  CHECK(classify("garbage\r\n") == PendingInput::Ordinary);                                   // a broken line gets 400 anyway
  CHECK(classify_pending("POST /api/stop HTTP/1.1\r\n", nullptr) == PendingInput::Ordinary);  // no priority set
}

TEST_CASE("a full lane of requests from a flood makes room for a stop from the flood's own address") {
  // The case the lane used to refuse: every waiter had sent something, so none was "silent" and evictable.
  const std::vector<LaneWaiter> lane{{"10.0.0.9", PendingInput::Ordinary}, {"10.0.0.9", PendingInput::Ordinary}};
  CHECK(choose_eviction(lane, "10.0.0.9") == 0u);
}

TEST_CASE("a stop in the lane is never evicted; when every waiter holds one the newcomer is refused") {
  const std::vector<LaneWaiter> stops{{"10.0.0.9", PendingInput::Priority}, {"10.0.0.2", PendingInput::Priority}};
  CHECK_FALSE(choose_eviction(stops, "10.0.0.9").has_value());
  const std::vector<LaneWaiter> mixed{{"10.0.0.9", PendingInput::Priority}, {"10.0.0.2", PendingInput::Partial}};
  CHECK(choose_eviction(mixed, "10.0.0.9") == 1u);
}

TEST_CASE("a waiter that will get 503 goes before a silent one, which goes before a trickling one") {
  const std::vector<LaneWaiter> lane{{"a", PendingInput::Partial}, {"b", PendingInput::Silent}, {"c", PendingInput::Ordinary}};
  CHECK(choose_eviction(lane, "z") == 2u);
  const std::vector<LaneWaiter> no_ordinary{{"a", PendingInput::Partial}, {"b", PendingInput::Silent}};
  CHECK(choose_eviction(no_ordinary, "z") == 1u);
}

TEST_CASE("within one kind: the newcomer's own address, then the address holding most of the lane, then the oldest") {
  const std::vector<LaneWaiter> lane{{"operator", PendingInput::Silent},
                                     {"flood", PendingInput::Silent},
                                     {"flood", PendingInput::Silent},
                                     {"newcomer", PendingInput::Silent},
                                     {"newcomer", PendingInput::Silent}};
  CHECK(choose_eviction(lane, "newcomer") == 3u);  // its own oldest, though "flood" holds as many
  CHECK(choose_eviction(lane, "stranger") == 1u);  // the largest share (a tie: the oldest of the tied)
  const std::vector<LaneWaiter> one_each{{"x", PendingInput::Silent}, {"y", PendingInput::Silent}};
  CHECK(choose_eviction(one_each, "z") == 0u);
}
