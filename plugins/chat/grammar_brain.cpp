#include "grammar_brain.hpp"

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <numbers>
#include <set>
#include <sstream>

#include "words.hpp"

namespace rcand::plugins::chat {
namespace {

using sdk::Json;
using Words = std::set<std::string, std::less<>>;

// ---- vocabulary ------------------------------------------------------------------------------------------------

const Words kFillers{"please", "robot", "the",  "a",    "an",     "your",    "my",    "now",   "for",    "by",
                     "of",     "to",    "at",   "with", "just",   "can",     "could", "would", "will",   "you",
                     "me",     "i",     "want", "need", "kindly", "hey",     "ok",    "okay",  "thanks", "thank",
                     "and",    "do",    "that", "it",   "this",   "exactly", "buddy", "again", "about",  "approximately",
                     "roughly"};
const Words kMoveVerbs{"go", "move", "drive", "head", "roll", "travel", "advance", "proceed", "walk", "ride", "come", "scoot"};
const Words kTurnVerbs{"turn", "rotate", "pivot", "face", "veer", "spin"};
const Words kForward{"forward", "forwards", "ahead", "straight", "onward", "onwards", "front"};
const Words kBackward{"back", "backward", "backwards", "rearward", "rearwards", "reverse"};
const Words kLeft{"left", "anticlockwise", "counterclockwise"};
const Words kRight{"right", "clockwise"};
const Words kSlow{"slowly", "slow", "gently", "carefully", "cautiously", "softly"};
const Words kFast{"quickly", "fast", "quick", "rapidly", "swiftly", "briskly"};
const Words kVery{"very", "really", "extra", "super"};
const Words kStopWords{"stop", "halt", "freeze", "estop", "abort", "brake", "emergency"};
const Words kStopExtras{"all",    "motors", "motor", "wheels",    "everything", "moving",   "immediately", "now",
                        "there",  "right",  "away",  "emergency", "engines",    "movement", "motion",      "completely",
                        "kill",   "cut",    "power", "off",       "shut",       "down",     "stop",        "halt",
                        "moving", "dead",   "in",    "its",       "tracks",     "stopped"};
const Words kNavWords{"navigation", "nav", "navigating", "job", "route", "waypoint", "trip", "mission", "goal", "current"};
const Words kHomeWords{"home", "origin", "start", "base", "dock"};
const Words kPlaceWords{"position", "point", "coordinates", "coordinate", "location", "spot", "starting"};
const Words kWhereExtras{"where",      "are",     "you",      "am",       "i",    "is",          "what",
                         "whats",      "current", "position", "location", "pose", "coordinates", "nav",
                         "navigation", "status",  "tell",     "right",    "now",  "report",      "show",
                         "give",       "heading", "facing",   "which",    "way",  "whereabouts", "located"};
const Words kStatusExtras{"status",  "health",     "diagnostics", "diagnostic", "report",  "what",  "whats",   "is",     "system",
                          "give",    "check",      "show",        "current",    "how",     "are",   "doing",   "ok",     "okay",
                          "alright", "fine",       "well",        "all",        "tell",    "state", "overall", "things", "going",
                          "run",     "everything", "working",     "good",       "feeling", "up",    "hows",    "today",  "there"};
const Words kVisionExtras{
    "what",         "whats",     "do",        "does",       "can",      "could",   "see",     "look",    "looking",  "around",
    "ahead",        "is",        "there",     "any",        "anything", "path",    "way",     "clear",   "in",       "front",
    "of",           "check",     "obstacles", "obstacle",   "show",     "take",    "picture", "photo",   "snapshot", "image",
    "capture",      "snap",      "camera",    "how",        "far",      "nearest", "closest", "detect",  "scan",     "are",
    "things",       "something", "view",      "photograph", "pic",      "near",    "nearby",  "blocked", "blocking", "obstructed",
    "surroundings", "seeing",    "describe",  "scene",      "away",     "thing",   "objects", "object",  "distance", "depth"};
const Words kSnapshotWords{"picture", "photo", "snapshot", "image", "photograph", "pic", "capture", "snap"};
const Words kGripNouns{"gripper", "claw", "hand", "jaws", "jaw", "pincer", "grabber"};
const Words kGripClose{"close", "grab", "grasp", "grip", "clamp", "shut", "pinch", "squeeze", "hold"};
const Words kGripOpen{"open", "release", "loosen", "drop", "let", "unclamp"};
const Words kGripExtras{"gripper", "claw",  "hand", "jaws", "jaw",  "pincer", "grabber",
                        "object",  "thing", "go",   "on",   "onto", "up"};
const Words kNegations{"not", "dont", "never", "no", "nothing", "cannot", "cant", "shouldnt", "wont"};
// Words that carry no meaning for matching a configured phrase.
const Words kPhraseNoise{"the", "a",    "an",     "your", "my",  "please", "robot", "now", "can", "could",  "would",
                         "you", "will", "kindly", "just", "hey", "ok",     "okay",  "me",  "for", "thanks", "thank"};

bool in(const Words& words, std::string_view w) { return words.find(w) != words.end(); }

// ---- units -----------------------------------------------------------------------------------------------------

enum class Kind { Length, Angle, Time };

std::optional<double> unit_factor(Kind kind, std::string_view u) {
  static const std::vector<std::pair<Words, double>> kLength{
      {{"m", "meter", "meters", "metre", "metres", "mtr", "mtrs"}, 1.0},
      {{"cm", "centimeter", "centimeters", "centimetre", "centimetres", "cms"}, 0.01},
      {{"mm", "millimeter", "millimeters", "millimetre", "millimetres"}, 0.001},
      {{"ft", "foot", "feet"}, 0.3048},
      {{"inch", "inches"}, 0.0254},
      {{"yard", "yards", "yd", "yds"}, 0.9144}};
  static const std::vector<std::pair<Words, double>> kAngle{
      {{"deg", "degree", "degrees", "degs"}, 1.0},
      {{"rad", "radian", "radians", "rads"}, 180.0 / std::numbers::pi},
      {{"turn", "turns", "revolution", "revolutions", "rotation", "rotations", "circle", "circles"}, 360.0}};
  static const std::vector<std::pair<Words, double>> kTime{{{"s", "sec", "secs", "second", "seconds"}, 1000.0},
                                                           {{"ms", "millisecond", "milliseconds", "msec", "msecs"}, 1.0},
                                                           {{"min", "mins", "minute", "minutes"}, 60000.0}};
  const auto& table = kind == Kind::Length ? kLength : kind == Kind::Angle ? kAngle : kTime;
  for (const auto& [names, factor] : table)
    if (in(names, u)) return factor;
  return std::nullopt;
}
bool any_unit(std::string_view u) {
  return unit_factor(Kind::Length, u) || unit_factor(Kind::Angle, u) || unit_factor(Kind::Time, u);
}

// ---- formatting ------------------------------------------------------------------------------------------------

double rounded(double v, double step) {
  const double r = std::round(v / step) * step;
  return r == 0.0 ? 0.0 : std::round(r * 1e6) / 1e6;  // no -0, no 0.30000000000000004
}
std::string fmt(double v) {
  std::ostringstream out;
  out << rounded(v, 0.001);
  return out.str();
}

// ---- one reading of an instruction -----------------------------------------------------------------------------

// The outcome of an intent: an action with the brain's reading of it, or the problem that made it not understood.
struct Outcome {
  Json action;
  std::string reading;
  std::string problem;
};
Outcome problem(std::string why) { return {nullptr, "", std::move(why)}; }
Outcome proposal(Json action, std::string reading) { return {std::move(action), std::move(reading), ""}; }

Json request(std::string method, std::string path, Json body = nullptr) {
  Json action{{"method", std::move(method)}, {"path", std::move(path)}};
  if (!body.is_null()) action["body"] = std::move(body);
  return action;
}

// Tokens with a used flag: each intent takes the words it understands, and whatever is left must be filler.
class Reading {
 public:
  explicit Reading(Tokens tokens) : t_(std::move(tokens)), used_(t_.size(), false) {}

  const Tokens& tokens() const noexcept { return t_; }
  std::size_t size() const noexcept { return t_.size(); }
  bool used(std::size_t i) const { return used_[i]; }
  void use(std::size_t from, std::size_t to) {
    for (std::size_t i = from; i < to && i < used_.size(); ++i) used_[i] = true;
  }

  std::optional<std::size_t> find(std::string_view w, std::size_t from = 0) const {
    for (std::size_t i = from; i < t_.size(); ++i)
      if (!used_[i] && t_[i] == w) return i;
    return std::nullopt;
  }
  bool has(std::string_view w) const { return find(w).has_value(); }
  bool has_any(const Words& words) const {
    for (std::size_t i = 0; i < t_.size(); ++i)
      if (!used_[i] && in(words, t_[i])) return true;
    return false;
  }
  bool take(std::string_view w) {
    if (auto i = find(w)) return used_[*i] = true;
    return false;
  }
  // Takes every unused occurrence of the words; returns the first one taken ("" when none).
  std::string take_all(const Words& words) {
    std::string first;
    for (std::size_t i = 0; i < t_.size(); ++i)
      if (!used_[i] && in(words, t_[i])) {
        used_[i] = true;
        if (first.empty()) first = t_[i];
      }
    return first;
  }
  // Two adjacent unused words.
  bool take_pair(std::string_view a, std::string_view b) {
    for (std::size_t i = 0; i + 1 < t_.size(); ++i)
      if (!used_[i] && !used_[i + 1] && t_[i] == a && t_[i + 1] == b) {
        used_[i] = used_[i + 1] = true;
        return true;
      }
    return false;
  }

  // "<number> <unit>" of `kind` (in metres, degrees or milliseconds), with "a metre and a half" too. Two of the same
  // kind make the instruction ambiguous: `error` is set.
  std::optional<double> take_quantity(Kind kind, std::string& error) {
    std::optional<double> found;
    for (std::size_t j = 0; j < t_.size(); ++j) {
      if (used_[j]) continue;
      std::optional<Number> n;
      double factor = 0;
      if ((t_[j] == "full" || t_[j] == "complete" || t_[j] == "whole") && kind == Kind::Angle && j + 1 < t_.size() &&
          unit_factor(Kind::Angle, t_[j + 1]) == 360.0) {
        n = Number{1.0, j + 1};  // "a full turn"
      } else {
        n = read_number(t_, j, any_unit);
      }
      if (!n || n->end >= t_.size() || free_range(j, n->end + 1) == false) continue;
      const auto f = unit_factor(kind, t_[n->end]);
      if (!f) continue;
      factor = *f;
      double value = n->value * factor;
      std::size_t end = n->end + 1;
      if (end + 2 < t_.size() + 0 && t_[end] == "and" && t_[end + 1] == "a" && t_[end + 2] == "half" &&
          free_range(end, end + 3)) {
        value += 0.5 * factor;
        end += 3;
      }
      if (found) {
        error = "two amounts of the same kind";
        return std::nullopt;
      }
      found = value;
      use(j, end);
      j = end - 1;
    }
    return found;
  }

  // A speed word or phrase, as a fraction of full speed.
  std::optional<double> take_speed() {
    const bool very = has_any(kVery);
    if (has_any(kSlow)) {
      take_all(kSlow);
      if (very) take_all(kVery);
      return very ? 0.1 : 0.25;
    }
    if (has_any(kFast)) {
      take_all(kFast);
      if (very) take_all(kVery);
      return very ? 1.0 : 0.8;
    }
    for (std::string_view full : {"full", "max", "maximum", "top"})
      for (std::string_view what : {"speed", "power", "throttle"})
        if (take_pair(full, what)) return 1.0;
    if (take_pair("half", "speed")) return 0.5;
    if (take_pair("quarter", "speed")) return 0.25;
    // "at 30 percent (speed)", "at speed 0.3", "speed of 0.3", "0.3 speed"
    if (auto percent = find("percent")) {
      if (auto n = number_ending_at(*percent)) {
        use(n->first, *percent + 1);
        if (*percent + 1 < t_.size() && (t_[*percent + 1] == "speed" || t_[*percent + 1] == "power"))
          use(*percent + 1, *percent + 2);
        return n->second / 100.0;
      }
    }
    if (auto at = find("speed")) {
      std::size_t from = *at + 1;
      if (from < t_.size() && t_[from] == "of") ++from;
      if (auto n = read_number(t_, from, nullptr); n && free_range(from, n->end)) {
        use(*at, n->end);
        return n->value;
      }
      if (auto n = number_ending_at(*at)) {
        use(n->first, *at + 1);
        return n->second;
      }
    }
    return std::nullopt;
  }

  // An unused bare number (no unit), for "turn left 45".
  std::optional<double> take_bare_number() {
    for (std::size_t j = 0; j < t_.size(); ++j) {
      if (used_[j]) continue;
      if (auto n = read_number(t_, j, nullptr); n && free_range(j, n->end)) {
        use(j, n->end);
        return n->value;
      }
    }
    return std::nullopt;
  }

  // Unused words that are neither filler nor in `allowed`.
  std::vector<std::string> leftovers(const Words& allowed) const {
    std::vector<std::string> out;
    for (std::size_t i = 0; i < t_.size(); ++i)
      if (!used_[i] && !in(kFillers, t_[i]) && !in(allowed, t_[i])) out.push_back(t_[i]);
    return out;
  }

 private:
  bool free_range(std::size_t from, std::size_t to) const {
    for (std::size_t i = from; i < to && i < used_.size(); ++i)
      if (used_[i]) return false;
    return true;
  }
  // A number whose last token is just before `end`: {first token, value}.
  std::optional<std::pair<std::size_t, double>> number_ending_at(std::size_t end) const {
    for (std::size_t back = 1; back <= 4 && back <= end; ++back) {
      const std::size_t start = end - back;
      if (auto n = read_number(t_, start, nullptr); n && n->end == end && free_range(start, end))
        return std::pair{start, n->value};
    }
    return std::nullopt;
  }

  Tokens t_;
  std::vector<bool> used_;
};

// ---- the robot's side: what is declared, and how a motion becomes a command ------------------------------------

class Robot {
 public:
  explicit Robot(const sdk::BrainContext& c) : c_(c) {}
  bool declares(std::string_view name) const {
    return std::find(c_.capabilities.begin(), c_.capabilities.end(), name) != c_.capabilities.end();
  }
  const std::optional<sdk::Pose2d>& pose() const noexcept { return c_.pose; }

  // Turn by `heading` degrees (left positive), then drive `distance` metres, at `speed`.
  Outcome drive(double distance, double heading, double speed, std::string reading) const {
    distance = rounded(distance, 0.0001);
    heading = rounded(heading, 0.001);
    speed = rounded(speed, 0.0001);
    if (declares("nav"))
      return proposal(
          request("POST", "/api/nav/waypoint", {{"distance_m", distance}, {"heading_deg", heading}, {"speed", speed}}),
          std::move(reading));
    // No nav: a single straight line or a turn on the spot is a timed teleop move, from the physics block.
    const Json physics = c_.limits.value("physics", Json::object());
    const double circumference = physics.value("wheel_circumference_m", 0.0), rps = physics.value("max_wheel_rps", 1.0);
    const double per_deg = physics.value("turn_time_per_deg_s", 0.0);
    if (declares("teleop") && speed > 0 && (distance == 0.0 || heading == 0.0)) {
      if (heading == 0.0 && circumference > 0 && rps > 0)
        return timed(std::copysign(speed, distance), 0.0, std::abs(distance) / (circumference * rps * speed) * 1000.0,
                     reading + " (timed from physics: no nav)");
      if (distance == 0.0 && per_deg > 0)
        return timed(0.0, std::copysign(speed, heading), std::abs(heading) * per_deg / speed * 1000.0,
                     reading + " (timed from physics: no nav)");
    }
    return problem("'" + reading + "' needs the nav capability" +
                   (declares("teleop") ? " (or the physics block, for a timed teleop move)" : ""));
  }

  Outcome timed(double linear, double angular, double ms, std::string reading) const {
    if (!declares("teleop")) return problem("'" + reading + "' needs the teleop capability");
    return proposal(request("POST", "/api/action",
                            {{"type", "move"},
                             {"linear", rounded(linear, 0.0001)},
                             {"angular", rounded(angular, 0.0001)},
                             {"duration_ms", static_cast<long long>(std::llround(ms))}}),
                    std::move(reading));
  }

 private:
  const sdk::BrainContext& c_;
};

Outcome finish(const Reading& r, Outcome outcome, const Words& allowed = {}) {
  if (!outcome.problem.empty()) return outcome;
  const auto rest = r.leftovers(allowed);
  if (rest.empty()) return outcome;
  std::string words;
  for (const auto& w : rest) words += (words.empty() ? "'" : ", '") + w + "'";
  const bool numeric = std::any_of(rest.begin(), rest.end(), [](const std::string& w) {
    return !w.empty() && (std::isdigit(static_cast<unsigned char>(w.back())) != 0);
  });
  return problem("I cannot place " + words + (numeric ? " (a number needs a unit: metres, degrees, seconds)" : ""));
}

// ---- intents, in the order they are tried ----------------------------------------------------------------------

Outcome stop_outcome() { return proposal(request("POST", "/api/stop", {{"reason", "chat"}}), "emergency stop"); }

std::optional<Outcome> negation(Reading& r) {
  if (!r.has_any(kNegations)) return std::nullopt;
  // "don't move" means stop; any other negation is not something to act on.
  if ((r.take("dont") || (r.take("do") && r.take("not"))) && (r.take("move") || r.take("go"))) {
    r.take("anywhere");
    return finish(r, stop_outcome(), kStopExtras);
  }
  return problem("I do not act on negations; say what to do (for example 'stop')");
}

std::optional<Outcome> cancel_nav(Reading& r, const Robot& robot) {
  const bool cancel = r.has("cancel");
  if (!cancel && !(r.has_any({"stop", "abort", "halt", "end"}) && r.has_any(kNavWords))) return std::nullopt;
  r.take_all({"cancel", "stop", "abort", "halt", "end"});
  r.take_all(kNavWords);
  if (!robot.declares("nav")) return problem("there is no navigation to cancel: this robot does not declare nav");
  return finish(r, proposal(request("POST", "/api/nav/cancel", Json::object()), "cancel the navigation job"));
}

std::optional<Outcome> stop(Reading& r) {
  const bool kill = (r.has("kill") || r.has("cut")) && r.has_any({"motors", "motor", "power"});
  if (!r.has_any(kStopWords) && !kill) return std::nullopt;
  r.take_all(kStopWords);
  return finish(r, stop_outcome(), kStopExtras);
}

std::optional<Outcome> go_to(Reading& r, const Robot& robot) {
  const auto& t = r.tokens();
  const bool verb = r.has_any(kMoveVerbs) || r.has("navigate") || r.has("return");
  if (!verb) return std::nullopt;
  std::optional<std::pair<double, double>> target;
  std::string name;
  // "go home", "return to the origin"
  for (std::size_t i = 0; i < t.size(); ++i)
    if (!r.used(i) && in(kHomeWords, t[i])) {
      target = std::pair{0.0, 0.0};
      name = t[i];
      r.use(i, i + 1);
      break;
    }
  if (!target) {
    const auto to = r.find("to");
    if (!to) return std::nullopt;
    std::size_t i = *to + 1;
    while (i < t.size() && (t[i] == "the" || in(kPlaceWords, t[i]))) ++i;
    auto number_at = [&](std::size_t& at) -> std::optional<double> {
      if (at < t.size() && (t[at] == "equals" || t[at] == "is")) ++at;
      auto n = read_number(t, at, nullptr);
      if (!n) return std::nullopt;
      at = n->end;
      return n->value;
    };
    const std::size_t start = i;
    std::optional<double> x, y;
    if (i < t.size() && t[i] == "x") {
      ++i;
      x = number_at(i);
      if (i < t.size() && t[i] == "and") ++i;
      if (i < t.size() && t[i] == "y") {
        ++i;
        y = number_at(i);
      }
    } else {
      x = number_at(i);
      if (x) {
        if (i < t.size() && t[i] == "and") ++i;
        y = number_at(i);
      }
    }
    if (!x && i == start) return std::nullopt;  // "go to the left": not a place
    if (!x || !y) return problem("go to where? give both coordinates: 'go to x 1 y 2' or 'navigate to 1.5, 2'");
    if (i < t.size() && unit_factor(Kind::Length, t[i])) {
      if (*unit_factor(Kind::Length, t[i]) != 1.0) return problem("coordinates are in metres");
      ++i;
    }
    target = std::pair{*x, *y};
    r.use(*to, i);
    name = "(" + fmt(*x) + ", " + fmt(*y) + ")";
  }
  r.take_all(kMoveVerbs);
  r.take_all({"navigate", "return", "back", "to"});
  r.take_all(kPlaceWords);
  if (!robot.declares("nav")) return problem("going to a place needs the nav capability");
  if (!robot.pose()) return problem("I do not know where the robot is (no pose source), so I cannot go to " + name);
  const auto& pose = *robot.pose();
  const double dx = target->first - pose.x_m, dy = target->second - pose.y_m;
  const double distance = std::hypot(dx, dy);
  const double heading =
      distance > 1e-9 ? std::remainder(std::atan2(dy, dx) * 180.0 / std::numbers::pi - pose.heading_deg, 360.0) : 0.0;
  std::string reading = "go to " + name + ": turn " + fmt(heading) + " degrees, drive " + fmt(distance) + " m";
  return finish(r, robot.drive(distance, heading, GrammarBrain::kDefaultSpeed, reading));
}

std::optional<Outcome> where(Reading& r, const Robot& robot) {
  const bool asks = (r.has("where") && r.has_any({"you", "am", "robot", "are", "is"})) ||
                    r.has_any({"position", "location", "pose", "coordinates", "whereabouts"}) ||
                    (r.has_any({"nav", "navigation"}) && r.has("status"));
  if (!asks) return std::nullopt;
  r.take_all(kWhereExtras);
  if (!robot.declares("nav")) return problem("this robot keeps no position: it does not declare nav");
  return finish(r, proposal(request("GET", "/api/nav/status"), "report the position and navigation status"));
}

std::optional<Outcome> status(Reading& r) {
  const bool asks = r.has_any({"status", "health", "diagnostics", "diagnostic", "report"}) ||
                    (r.has_any({"how", "hows"}) && r.has_any({"you", "things", "going", "doing"})) ||
                    (r.has("are") && r.has("you") && r.has_any({"ok", "okay", "alright", "fine", "well", "working"})) ||
                    (r.has_any({"what", "whats"}) && r.has("going") && r.has("on"));
  if (!asks) return std::nullopt;
  r.take_all(kStatusExtras);
  r.take("on");
  r.take_all({"you"});
  return finish(r, proposal(request("GET", "/api/status"), "report status"));
}

std::optional<Outcome> vision(Reading& r, const Robot& robot) {
  const bool sees = (r.has("see") || r.has("seeing")) || (r.has("look") && !r.has_any(kMoveVerbs)) ||
                    r.has_any({"obstacle", "obstacles", "camera", "surroundings", "scene"}) || r.has_any(kSnapshotWords) ||
                    (r.has("clear") && r.has_any({"path", "way"})) || (r.has("in") && r.has("front") && r.has("what")) ||
                    (r.has_any({"what", "whats"}) && r.has("ahead") && !r.has_any(kMoveVerbs)) ||
                    (r.has("way") && r.has_any({"anything", "something", "obstacle", "obstacles"}));
  if (!sees) return std::nullopt;
  const bool snapshot = r.has_any(kSnapshotWords);
  r.take_all(kVisionExtras);
  if (!robot.declares("vision")) return problem("this robot has no camera: it does not declare vision");
  if (snapshot) return finish(r, proposal(request("GET", "/api/stream/snapshot"), "take a picture"));
  return finish(r, proposal(request("GET", "/api/depth/obstacles"), "report what the depth camera sees: obstacle distances"));
}

std::optional<Outcome> grip(Reading& r, const Robot& robot) {
  const bool noun = r.has_any(kGripNouns);
  const bool verb = r.has_any({"grab", "grasp", "grip", "release", "clamp", "pinch", "unclamp"});
  if (!noun && !verb) return std::nullopt;
  const bool close = r.has_any(kGripClose), open = r.has_any(kGripOpen);
  r.take_all(kGripClose);
  r.take_all(kGripOpen);
  r.take_all(kGripExtras);
  if (close == open) return problem("open or close the gripper?");
  if (!robot.declares("arm"))
    return problem("this robot declares no arm; a custom gripper answers only the phrases configured for it");
  const std::string state = close ? "close" : "open";
  return finish(r, proposal(request("POST", "/api/action", {{"type", "grip"}, {"state", state}}), state + " the gripper"));
}

// Turns, drives and timed moves.
std::optional<Outcome> motion(Reading& r, const Robot& robot) {
  std::string error;
  const auto speed_word = r.take_speed();
  const auto distance = r.take_quantity(Kind::Length, error);
  const auto angle = r.take_quantity(Kind::Angle, error);
  const auto duration = r.take_quantity(Kind::Time, error);

  const bool spin = r.take("spin");
  const bool turn = spin || !r.take_all({"turn", "rotate", "pivot", "face", "veer"}).empty();
  const bool back_up = r.take_pair("back", "up") || r.take_pair("back", "off") || !r.take_all({"backup", "retreat"}).empty();
  const bool move_verb = !r.take_all(kMoveVerbs).empty();
  const bool reverse_verb = r.take("reverse");
  const bool forward = !r.take_all(kForward).empty();
  const bool backward = back_up || reverse_verb || !r.take_all(kBackward).empty();
  const bool ccw = r.take_pair("counter", "clockwise") || r.take_pair("anti", "clockwise");
  const bool left = ccw || !r.take_all(kLeft).empty();
  const bool right = !r.take_all(kRight).empty();
  const bool around = r.take("around");
  if (!turn && !move_verb && !forward && !backward) {
    if (speed_word || distance || angle || duration || left || right) return problem("move how? say go, turn or spin");
    return std::nullopt;
  }
  if (!error.empty()) return problem(error + ": give one distance, one angle or one duration");
  for (auto q : {distance, angle, duration})
    if (q && *q < 0) return problem("say 'back' or 'right' instead of a negative amount");
  if (left && right) return problem("left or right?");
  if (forward && backward) return problem("forward or back?");
  const double speed = speed_word.value_or(GrammarBrain::kDefaultSpeed);
  const std::string at = " at speed " + fmt(speed);
  const double sign = backward ? -1.0 : 1.0;

  if (turn || around) {
    if (!left && !right && !around) return finish(r, problem("turn which way? say left or right"));
    const double side = right ? -1.0 : 1.0;  // left (counter-clockwise) is positive, as nav's heading_deg
    const std::string way = right ? "right" : "left";
    std::optional<double> degrees = angle;
    if (!degrees && !spin) degrees = r.take_bare_number();  // "turn left 45": degrees
    if (!degrees && around) degrees = spin ? 360.0 : 180.0;
    if (distance) {  // turn, then drive: one waypoint
      if (duration) return problem("give a distance or a duration, not both");
      const double heading = side * degrees.value_or(90.0);
      return finish(r, robot.drive(sign * *distance, heading, speed,
                                   "turn " + fmt(heading) + " degrees, then drive " + fmt(sign * *distance) + " m" + at));
    }
    if (move_verb || forward || backward) return problem("turn, then go how far? for example 'turn left and go forward 1 metre'");
    if (!degrees) {
      if (spin || duration) {  // a continuous spin, timed
        const double ms = duration.value_or(GrammarBrain::kDefaultMoveMs);
        return finish(r, robot.timed(0.0, side * speed, ms, "spin " + way + " for " + fmt(ms / 1000.0) + " s" + at));
      }
      degrees = 90.0;
    }
    if (duration) return problem("give an angle or a duration, not both");
    const double heading = side * *degrees;
    return finish(r, robot.drive(0.0, heading, speed, "turn " + way + " " + fmt(*degrees) + " degrees" + at));
  }

  if (left || right) {  // "go left 1 metre": a quarter turn, then the drive
    if (!distance) return problem("go " + std::string(left ? "left" : "right") + " how far? for example 'go left 1 metre'");
    const double heading = left ? 90.0 : -90.0;
    return finish(r, robot.drive(sign * *distance, heading, speed,
                                 "turn " + fmt(heading) + " degrees, then drive " + fmt(sign * *distance) + " m" + at));
  }
  if (angle) return problem("an angle needs a turn: for example 'turn left 90 degrees'");
  if (distance && duration) return problem("give a distance or a duration, not both");
  const std::string way = backward ? "back" : "forward";
  if (distance) return finish(r, robot.drive(sign * *distance, 0.0, speed, "drive " + way + " " + fmt(*distance) + " m" + at));
  if (!forward && !backward && !duration) {
    const auto rest = r.leftovers({});
    if (!rest.empty()) return finish(r, problem(""));
    return problem("go where? for example 'go forward 1 metre'");
  }
  const double ms = duration.value_or(GrammarBrain::kDefaultMoveMs);
  return finish(r, robot.timed(sign * speed, 0.0, ms, "drive " + way + " for " + fmt(ms / 1000.0) + " s" + at));
}

// ---- typo correction, phrases and suggestions ------------------------------------------------------------------

const Words& vocabulary() {
  static const Words words = [] {
    Words all;
    for (const Words* set :
         {&kFillers,      &kMoveVerbs,    &kTurnVerbs,     &kForward,    &kBackward,  &kLeft,      &kRight,      &kSlow,
          &kFast,         &kVery,         &kStopWords,     &kStopExtras, &kNavWords,  &kHomeWords, &kPlaceWords, &kWhereExtras,
          &kStatusExtras, &kVisionExtras, &kSnapshotWords, &kGripNouns,  &kGripClose, &kGripOpen,  &kGripExtras, &kNegations})
      all.insert(set->begin(), set->end());
    for (std::string_view w :
         {"zero",        "one",         "two",        "three",       "four",        "five",         "six",        "seven",
          "eight",       "nine",        "ten",        "eleven",      "twelve",      "thirteen",     "fourteen",   "fifteen",
          "sixteen",     "seventeen",   "eighteen",   "nineteen",    "twenty",      "thirty",       "forty",      "fifty",
          "sixty",       "seventy",     "eighty",     "ninety",      "hundred",     "half",         "quarter",    "quarters",
          "point",       "couple",      "meter",      "meters",      "metre",       "metres",       "centimeter", "centimeters",
          "centimetre",  "centimetres", "millimeter", "millimetres", "foot",        "feet",         "inch",       "inches",
          "yard",        "yards",       "degree",     "degrees",     "radian",      "radians",      "turns",      "revolution",
          "revolutions", "rotation",    "second",     "seconds",     "millisecond", "milliseconds", "minute",     "minutes",
          "speed",       "percent",     "navigate",   "cancel",      "around",      "spin",         "turn",       "rotate",
          "pivot",       "counter",     "anti",       "full",        "maximum",     "speed",        "power",      "where",
          "status",      "reverse",     "equals"})
      all.emplace(w);
    return all;
  }();
  return words;
}

// Replaces unknown words one edit away from exactly one known word ("foward" -> forward). Returns the corrections.
std::vector<std::string> correct(Tokens& tokens, const Words& extra) {
  std::vector<std::string> corrections;
  for (auto& token : tokens) {
    if (token.size() < 4 || in(vocabulary(), token) || in(extra, token) || any_unit(token)) continue;
    if (!std::all_of(token.begin(), token.end(), [](char c) { return c >= 'a' && c <= 'z'; })) continue;
    // One known word one edit away; among several, the only one of the same length (a swap or a wrong letter:
    // "trun" is turn, not run).
    std::vector<std::string> near;
    auto consider = [&](const std::string& word) {
      if (word.size() >= 3 && edit_distance(token, word, 1) <= 1 && std::find(near.begin(), near.end(), word) == near.end())
        near.push_back(word);
    };
    for (const auto& word : vocabulary()) consider(word);
    for (const auto& word : extra) consider(word);
    if (near.size() > 1) std::erase_if(near, [&](const std::string& word) { return word.size() != token.size(); });
    if (near.size() == 1) {
      corrections.push_back(token + "->" + near.front());
      token = near.front();
    }
  }
  return corrections;
}

Tokens phrase_key(const Tokens& tokens) {
  Tokens key;
  for (const auto& t : tokens)
    if (!in(kPhraseNoise, t)) key.push_back(t);
  return key;
}

std::vector<std::string> examples(const Robot& robot, const sdk::BrainContext& context) {
  std::vector<std::string> out{"stop", "status"};
  auto add = [&](bool when, std::initializer_list<const char*> texts) {
    if (when) out.insert(out.end(), texts.begin(), texts.end());
  };
  const bool moves = robot.declares("nav") || robot.declares("teleop");
  add(moves, {"go forward 1 metre", "turn left 90 degrees", "drive back half a metre slowly", "turn right 45 degrees"});
  add(robot.declares("teleop"), {"go forward for 2 seconds", "spin right"});
  add(robot.declares("nav"), {"go to x 1 y 2", "where are you", "cancel navigation", "turn left and go forward 1 metre"});
  add(robot.declares("vision"), {"what do you see", "take a picture"});
  add(robot.declares("arm"), {"open the gripper", "close the gripper"});
  for (const auto& phrase : context.phrases) out.push_back(phrase.text);
  return out;
}

// The known commands closest to what was said: shared (or nearly shared) words, then the shorter command.
std::vector<std::string> suggestions(const Tokens& said, const Robot& robot, const sdk::BrainContext& context) {
  std::vector<std::pair<double, std::string>> scored;
  const auto all = examples(robot, context);
  for (const auto& example : all) {
    const Tokens words = tokenize(example).value_or(Tokens{});
    double score = 0;
    for (const auto& w : said) {
      if (in(kFillers, w)) continue;
      for (const auto& e : words)
        if (e == w || (w.size() >= 4 && edit_distance(e, w, 1) <= 1)) {
          score += 1;
          break;
        }
    }
    scored.emplace_back(words.empty() ? 0 : score / std::sqrt(static_cast<double>(words.size())), example);
  }
  std::stable_sort(scored.begin(), scored.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<std::string> out;
  for (const auto& [score, text] : scored)
    if (out.size() < 3) out.push_back(text);
  return out;
}

}  // namespace

sdk::Proposal GrammarBrain::understand(std::string_view instruction, const sdk::BrainContext& context) {
  sdk::Proposal p;
  p.brain = std::string(kProvider);
  p.model = std::string(kModel);
  const Robot robot(context);
  auto tokens = tokenize(instruction);
  auto not_understood = [&](const std::string& why, const Tokens& said) {
    p.action = nullptr;
    p.raw_text = "not understood: " + why;
    p.suggestions = suggestions(said, robot, context);
    p.confidence = 0.0;
    return p;
  };
  if (!tokens) return not_understood("I understand English commands only (plain ASCII letters and digits)", {});
  if (tokens->empty()) return not_understood("there are no words to read", {});

  // Phrases the robot config declares come first, read exactly (only filler words may differ).
  Words phrase_words;
  std::vector<std::pair<Tokens, const sdk::BrainPhrase*>> phrases;
  for (const auto& phrase : context.phrases) {
    Tokens words = tokenize(phrase.text).value_or(Tokens{});
    phrase_words.insert(words.begin(), words.end());
    phrases.emplace_back(phrase_key(words), &phrase);
  }
  const auto corrections = correct(*tokens, phrase_words);
  const double confidence = corrections.empty() ? 1.0 : std::max(0.5, 1.0 - 0.15 * static_cast<double>(corrections.size()));
  std::string note;
  for (const auto& c : corrections) note += (note.empty() ? " (read " : ", ") + c;
  if (!note.empty()) note += ")";

  const Tokens key = phrase_key(*tokens);
  for (const auto& [words, phrase] : phrases)
    if (!words.empty() && words == key) {
      p.action = phrase->action;
      p.raw_text = phrase->text + note;
      p.confidence = confidence;
      return p;
    }

  Reading r(*tokens);
  std::optional<Outcome> outcome;
  for (auto intent : std::initializer_list<std::optional<Outcome> (*)(Reading&, const Robot&)>{
           [](Reading&x, const Robot&) { return negation(x); }, cancel_nav, [](Reading&x, const Robot&) { return stop(x); },
           go_to, where, [](Reading&x, const Robot&) { return status(x); }, vision, grip, motion}) {
    outcome = intent(r, robot);
    if (outcome) break;
  }
  if (!outcome) outcome = finish(r, problem(""));
  if (!outcome->problem.empty() || outcome->action.is_null())
    return not_understood(outcome->problem.empty() ? "I know no command like that" : outcome->problem, *tokens);
  p.action = std::move(outcome->action);
  p.raw_text = outcome->reading + note;
  p.confidence = confidence;
  return p;
}

sdk::Proposal GrammarBrain::propose(const sdk::BrainRequest& request, const sdk::BrainContext& context,
                                    sdk::CancelToken cancel) const noexcept {
  try {
    if (cancel.cancelled()) {
      sdk::Proposal p;
      p.brain = std::string(kProvider);
      p.model = std::string(kModel);
      p.error = "cancelled";
      return p;
    }
    return understand(request.instruction, context);
  } catch (const std::exception& e) {  // no memory: an error the chain can fall back from
    sdk::Proposal p;
    p.brain = std::string(kProvider);
    p.model = std::string(kModel);
    p.error = std::string("grammar brain failed: ") + e.what();
    return p;
  }
}

}  // namespace rcand::plugins::chat
