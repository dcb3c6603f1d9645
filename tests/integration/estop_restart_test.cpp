// The e-stop latch across restarts (runtime.state_dir): a crash (kill -9) or a stop while latched brings rcand back
// latched, with the reason in GET /api/estop and an audit entry; a clean stop while unlatched comes back unlatched;
// safety.estop_on_startup still forces the latch; a disk that fills up loses no stop's reason; an unusable or shared
// state dir is a startup error naming the key.
#include <doctest/doctest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "eventually.hpp"
#include "rcand_process.hpp"
#include "small_filesystem.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

const std::string kRestartMove = R"({"type":"move","linear":0.3,"angular":0.0,"duration_ms":300})";

// The sim robot with the state dir (and the audit file) in `shared`, so that processes run in turn share them.
json restart_config(const TempDir& shared) {
  auto config = sim_config();
  config["runtime"]["state_dir"] = (shared.path() / "state").string();
  config["runtime"]["audit_file"] = (shared.path() / "audit.jsonl").string();
  return config;
}

std::string restart_read_file(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

int restart_move_status(const RcandProcess& rcand) {
  int status = 0;
  rcand.json("POST", "/api/action", "user-token", kRestartMove, &status);
  return status;
}

// The newest in-memory audit entry whose event is `event` (null when none).
json restart_audit_entry(const RcandProcess& rcand, const std::string& event) {
  const auto audit = rcand.json("GET", "/api/audit?limit=100", "owner-token");  // kept: the loop reads into it
  for (const auto& entry : audit["entries"])
    if (entry.value("event", "") == event) return entry;
  return nullptr;
}

}  // namespace

TEST_CASE("state dir: after kill -9 rcand starts latched, says why in GET /api/estop, and audits it") {
  TempDir shared;
  const auto config = restart_config(shared);
  {
    RcandProcess first(config);
    CHECK(first.json("GET", "/api/estop", "guest-token")["estopped"] == false);
    CHECK(restart_move_status(first) == 200);
    CHECK(first.kill_hard() == 128 + 9);  // no clean shutdown: the running marker stays
  }
  RcandProcess second(config);
  const auto estop = second.json("GET", "/api/estop", "guest-token");
  CHECK(estop["estopped"] == true);
  CHECK(estop["source"] == "startup");
  CHECK(estop["reason"].get<std::string>().find("without a clean shutdown") != std::string::npos);
  CHECK(estop["since_ms"].is_number());
  CHECK(restart_move_status(second) == 423);  // nothing moves until someone clears it
  CHECK(drive_status(second)["moving"] == false);

  const auto entry = restart_audit_entry(second, "e-stop latched at startup");
  REQUIRE(entry.is_object());
  CHECK(entry["principal"] == "rcand");
  CHECK(entry["outcome"] == "ok");
  CHECK(entry["detail"].get<std::string>().find("without a clean shutdown") != std::string::npos);
  CHECK(restart_read_file(shared.path() / "audit.jsonl").find("e-stop latched at startup") != std::string::npos);

  // Cleared and stopped cleanly: the next start is unlatched.
  int status = 0;
  second.json("POST", "/api/estop/clear", "owner-token", "", &status);
  CHECK(status == 200);
  CHECK(second.stop() == 0);
  RcandProcess third(config);
  CHECK(third.json("GET", "/api/estop", "guest-token")["estopped"] == false);
  CHECK(restart_move_status(third) == 200);
}

TEST_CASE("state dir: a clean stop keeps the latch as it was; safety.estop_on_startup still forces it") {
  TempDir shared;
  auto config = restart_config(shared);
  {
    RcandProcess first(config);
    int status = 0;
    first.json("POST", "/api/stop", "guest-token", R"({"reason":"operator pressed stop"})", &status);
    REQUIRE(status == 200);
    CHECK(first.stop() == 0);  // clean, while latched
  }
  {
    RcandProcess second(config);
    const auto estop = second.json("GET", "/api/estop", "guest-token");
    CHECK(estop["estopped"] == true);
    CHECK(estop["source"] == "startup");
    const auto reason = estop["reason"].get<std::string>();
    CHECK(reason.find("latched when rcand last stopped") != std::string::npos);
    CHECK(reason.find("operator pressed stop") != std::string::npos);
    CHECK(reason.find("clean shutdown") == std::string::npos);  // it was a clean one
    CHECK(restart_move_status(second) == 423);
    CHECK(restart_audit_entry(second, "e-stop latched at startup").is_object());
    int status = 0;
    second.json("POST", "/api/estop/clear", "owner-token", "", &status);
    CHECK(status == 200);
    CHECK(second.stop() == 0);  // clean, unlatched
  }
  {
    RcandProcess third(config);
    CHECK(third.json("GET", "/api/estop", "guest-token")["estopped"] == false);
    CHECK(restart_audit_entry(third, "e-stop latched at startup").is_null());
    CHECK(restart_move_status(third) == 200);
    CHECK(third.stop() == 0);
  }
  config["safety"]["estop_on_startup"] = true;
  {
    RcandProcess forced(config);
    const auto estop = forced.json("GET", "/api/estop", "guest-token");
    CHECK(estop["estopped"] == true);
    CHECK(estop["reason"] == "safety.estop_on_startup");
    CHECK(restart_move_status(forced) == 423);
    CHECK(forced.kill_hard() == 128 + 9);
  }
  {
    RcandProcess both(config);  // forced by the config AND after a crash: the reason names both
    const auto reason = both.json("GET", "/api/estop", "guest-token")["reason"].get<std::string>();
    CHECK(reason.find("without a clean shutdown") != std::string::npos);
    CHECK(reason.find("safety.estop_on_startup") != std::string::npos);
  }
}

TEST_CASE("state dir: a stop latched just before kill -9 is named at the restart") {
  TempDir shared;
  const auto config = restart_config(shared);
  {
    RcandProcess first(config);
    int status = 0;
    first.json("POST", "/api/stop", "guest-token", R"({"reason":"bumper hit"})", &status);
    REQUIRE(status == 200);
    first.kill_hard();
  }
  RcandProcess second(config);
  const auto reason = second.json("GET", "/api/estop", "guest-token")["reason"].get<std::string>();
  CHECK(reason.find("without a clean shutdown") != std::string::npos);
  // The latch record is written off the stop path, so it may or may not have made it before the kill; the
  // running marker alone is what makes this start latched.
  CHECK(second.json("GET", "/api/estop", "guest-token")["estopped"] == true);
}

TEST_CASE("state dir: a stop while the disk is full is named at the restart, after a crash and after a clean stop") {
  TempDir shared;
  SmallFilesystem disk(shared.path() / "small", 256 * 1024);
  if (!disk.mounted()) {
    REQUIRE_MESSAGE(!disk.root(), disk.why_not());  // as root (CI) the small filesystem must be made: never skipped
    MESSAGE("SKIPPED: " << disk.why_not());
    return;
  }
  auto config = sim_config();
  config["runtime"]["state_dir"] = (disk.path() / "state").string();
  const auto stop_on_full_disk = [&disk](const RcandProcess& rcand, const std::string& reason) {
    const auto failed_writes = [&rcand] { return rcand.stderr_text().find("No space left on device") != std::string::npos; };
    // What the restart reads: the reserved slot holds this stop (the writer may first have written another record,
    // the startup one, and failed on estop.json with it).
    const auto slot_holds_reason = [&disk, &reason] {
      std::ifstream in(disk.path() / "state" / "estop.slot");
      std::stringstream text;
      text << in.rdbuf();
      return text.str().find(reason) != std::string::npos;
    };
    REQUIRE_FALSE(failed_writes());
    REQUIRE(disk.fill());
    int status = 0;
    rcand.json("POST", "/api/stop", "guest-token", json{{"reason", reason}}.dump(), &status);
    REQUIRE(status == 200);
    REQUIRE(eventually(failed_writes));  // estop.json could not be replaced: the disk is full
    REQUIRE(eventually(slot_holds_reason));
  };
  {
    RcandProcess first(config);
    stop_on_full_disk(first, "bumper hit on a full disk");
    first.kill_hard();
  }
  disk.unfill();  // the operator makes room and starts it again
  {
    RcandProcess second(config);
    const auto reason = second.json("GET", "/api/estop", "guest-token")["reason"].get<std::string>();
    CHECK(reason.find("without a clean shutdown") != std::string::npos);
    CHECK(reason.find("bumper hit on a full disk") != std::string::npos);
    int status = 0;
    second.json("POST", "/api/estop/clear", "owner-token", "", &status);
    REQUIRE(status == 200);
    stop_on_full_disk(second, "cliff sensor on a full disk");
    CHECK(second.stop() == 0);
  }
  disk.unfill();
  RcandProcess third(config);
  const auto reason = third.json("GET", "/api/estop", "guest-token")["reason"].get<std::string>();
  CHECK(reason.rfind("latched when rcand last stopped: cliff sensor on a full disk", 0) == 0);
  CHECK(reason.find("clean shutdown") == std::string::npos);  // the record was kept, so the stop counted as clean
}

TEST_CASE("state dir: unusable or already in use is a startup error naming runtime.state_dir") {
  TempDir scratch;
  auto config = sim_config();
  scratch.write("jwt.secret", kJwtSecret);
  SUBCASE("a file where the directory should be") {
    const auto file = scratch.write("not-a-dir", "x");
    config["runtime"]["state_dir"] = file.string();
    const auto config_file = scratch.write("robot.rcan.yaml", config.dump());
    const auto result =
        run_tool(rcand_binary(), {"--config", config_file.string(), "--port", "0", "--plugin-path", plugin_dir().string()});
    CHECK(result.exit_code == 1);
    CHECK(result.err.find("runtime.state_dir") != std::string::npos);
    CHECK(result.err.find(file.string()) != std::string::npos);
  }
  SUBCASE("a second rcand on the same state dir") {
    config["runtime"]["state_dir"] = (scratch.path() / "state").string();
    RcandProcess running(config);
    const auto config_file = scratch.write("robot.rcan.yaml", config.dump());
    const auto result =
        run_tool(rcand_binary(), {"--config", config_file.string(), "--port", "0", "--plugin-path", plugin_dir().string()});
    CHECK(result.exit_code == 1);
    CHECK(result.err.find("runtime.state_dir") != std::string::npos);
    CHECK(result.err.find("in use by another rcand") != std::string::npos);
    CHECK(running.json("GET", "/api/estop", "guest-token")["estopped"] == false);  // the first one is unaffected
  }
}
