// An in-process simulated robot for the fuzz targets that go through the HTTP API: one Kernel (sim drive, teleop,
// nav, the sim arm, the vendor gripper, R2R, two swarm peers that refuse connections) built once, answering
// Api::handle synchronously exactly as the server's session would hand it requests. No socket, no HTTP server:
// microseconds per request. serve_robot() starts its real server too, for what only a socket reaches (WebSockets).
#pragma once

#include <cstdint>
#include <string>

#include "libs/http/request.hpp"
#include "libs/http/response.hpp"

namespace rcand::fuzz {

namespace http = rcand::http;

inline constexpr const char* kOwnerToken = "fuzz-owner-token";  // pre-shared, role OWNER (every scope)
inline constexpr const char* kGuestToken = "fuzz-guest-token";  // pre-shared, role GUEST (status only)

// Answers one request through the real Api of the shared robot, as the session does (an exception escaping the
// handler, or a Respond dropped unanswered, becomes the 500 the server would send). Checks the answer's invariants:
// a valid status, never 500, and every error a JSON {"error","code","status"} with a non-empty code.
http::Response call(http::Request request);

// A request as the session builds it (method upper case, header names lower case), with the owner's token.
http::Request owner_request(std::string method, std::string path, std::string body = {});

// Starts the robot's HTTP server on 127.0.0.1 (once; later calls return the same port): WS /ws/telemetry and
// /ws/r2r, authenticated with kOwnerToken like any request.
std::uint16_t serve_robot();

// Puts the robot back in a state where every route can run: clears the e-stop and cancels a nav job. Between inputs,
// so one input's stop does not hide the motion handlers from every later one.
void reset_robot();

}  // namespace rcand::fuzz
