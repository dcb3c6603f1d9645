// What chat answers as `action`: the ecosystem's action object (the reference runtime's `{"type": "move", ...}`
// vocabulary, which its client library, app and MCP bridges read), derived from the request chat dispatches (which
// it answers as `request`). docs/protocol.md §7.5 lists every type.
#pragma once

#include <rcand/sdk/http.hpp>

namespace rcand::plugins::chat {

// The action object of a dispatchable request {"method","path","body"}: a body with a "type" sent to /api/action
// is its own action object; rcand's and the standard capabilities' routes a brain may use map to a type of their
// own; a custom capability's route is {"type":"custom","capability","route","body"}; any other request is
// {"type":"request","method","path","body"?}. Null (no action) and anything not shaped as a request give null.
sdk::Json action_object(const sdk::Json& request);

}  // namespace rcand::plugins::chat
