#include "vision.hpp"

#include "jpeg_encoder.hpp"
#include "snapshot_client.hpp"
#include "stream_metrics.hpp"

#include <opencv2/core/utils/logger.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <set>

namespace rcand::plugins::vision {
namespace {

using sdk::ConfigError;
using sdk::ConfigView;

SourceKind kind_of(const std::string& type) {
  static const std::vector<std::pair<std::set<std::string>, SourceKind>> kTypes{
      {{"synthetic", "test", "test_pattern"}, SourceKind::Synthetic},
      {{"file", "video"}, SourceKind::File},
      {{"v4l2", "usb", "csi", "webcam", "uvc"}, SourceKind::V4l2},
      {{"url", "ip", "http", "rtsp", "mjpeg", "stream"}, SourceKind::Url},
      {{"snapshot", "http_snapshot", "jpeg"}, SourceKind::Snapshot}};
  for (const auto& [names, kind] : kTypes)
    if (names.contains(type)) return kind;
  throw ConfigError("camera.type: unknown camera type '" + type.substr(0, 64) +
                    "'; one of synthetic, file, v4l2 (usb, csi), url (http, rtsp), snapshot");
}

// `device` as a path: 2 and "2" are /dev/video2.
std::string device_path(const ConfigView& camera) {
  const auto& raw = camera.raw();
  if (!raw.contains("device")) return "/dev/video0";
  const auto& device = raw["device"];
  if (device.is_number_integer() && device.get<long>() >= 0) return "/dev/video" + std::to_string(device.get<long>());
  if (!device.is_string() || device.get<std::string>().empty())
    throw ConfigError("camera.device: expected a device path such as /dev/video0, or its number");
  const auto text = device.get<std::string>();
  if (std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; })) return "/dev/video" + text;
  return text;
}

void read_size(const ConfigView& camera, SourceSettings& s) {
  const auto& raw = camera.raw();
  if (raw.contains("resolution")) {
    const auto& r = raw["resolution"];
    if (!r.is_array() || r.size() != 2 || !r[0].is_number_integer() || !r[1].is_number_integer())
      throw ConfigError("camera.resolution: expected [width, height] in pixels, e.g. [640, 480]");
    s.width = r[0].get<int>();
    s.height = r[1].get<int>();
  }
  s.size_given = raw.contains("resolution") || raw.contains("width") || raw.contains("height");
  s.width = camera.get<int>("width").value_or(s.width);
  s.height = camera.get<int>("height").value_or(s.height);
  if (s.width < 16 || s.width > 7680 || s.height < 16 || s.height > 4320)
    throw ConfigError("camera.resolution: " + std::to_string(s.width) + "x" + std::to_string(s.height) +
                      " is outside 16x16 to 7680x4320");
}

SourceSettings read_source(const ConfigView& camera, const ConfigView& own) {
  SourceSettings s;
  const auto type = camera.get<std::string>("type");
  if (type) s.kind = kind_of(*type);
  else if (camera.has("url")) s.kind = SourceKind::Url;
  else if (camera.has("path") || camera.has("file")) s.kind = SourceKind::File;
  else s.kind = SourceKind::V4l2;  // a camera block names a camera: never a silent test pattern
  read_size(camera, s);
  const auto fps = camera.get<double>("fps") ? camera.get<double>("fps") : camera.get<double>("framerate");
  if (fps && !(*fps > 0 && *fps <= 240)) throw ConfigError("camera.fps: must be in (0, 240]");
  s.fps = fps.value_or(s.kind == SourceKind::File ? 0.0 : 30.0);
  s.fourcc = camera.get<std::string>("fourcc").value_or("");
  if (!s.fourcc.empty() && s.fourcc.size() != 4) throw ConfigError("camera.fourcc: expected 4 characters, e.g. MJPG or YUYV");
  switch (s.kind) {
    case SourceKind::Synthetic: break;
    case SourceKind::V4l2: s.location = device_path(camera); break;
    case SourceKind::File:
      s.location = camera.get<std::string>("path").value_or(camera.get<std::string>("file").value_or(""));
      if (s.location.empty()) throw ConfigError("camera.path: a file camera needs the video file's path");
      break;
    case SourceKind::Url:
      s.location = camera.get<std::string>("url").value_or("");
      if (s.location.empty()) throw ConfigError("camera.url: a url camera needs its URL (http://... or rtsp://...)");
      break;
    case SourceKind::Snapshot: {
      s.location = camera.get<std::string>("url").value_or("");
      std::string error;
      if (s.location.empty()) error = "a snapshot camera needs the URL of its picture (http://cam/snapshot.jpg)";
      else if (!parse_snapshot_url(s.location, error)) error = redact_url(s.location) + ": " + error;
      if (!error.empty()) throw ConfigError("camera.url: " + error);
      break;
    }
  }
  s.open_timeout = std::chrono::milliseconds(own.get_or<int>("open_timeout_ms", 3000));
  s.read_timeout = std::chrono::milliseconds(own.get_or<int>("read_timeout_ms", 3000));
  s.snapshot_max_bytes = static_cast<std::size_t>(own.get_or<int>("snapshot_max_kib", 8192)) * 1024;
  return s;
}

DepthSettings read_depth(const ConfigView& camera, const ConfigView& own) {
  DepthSettings d;
  const auto& raw = camera.raw();
  // Absent, null or false: no depth (as the obstacle guard of nav and teleop reads it).
  if (raw.contains("depth") && !raw["depth"].is_null() && !(raw["depth"].is_boolean() && !raw["depth"].get<bool>())) {
    // Only the synthetic scene so far: `true` would have to pick a source, and a camera's depth is never silently
    // replaced by a made-up one.
    if (!(raw["depth"].is_string() && raw["depth"].get<std::string>() == "synthetic"))
      throw ConfigError("camera.depth: 'synthetic' (the synthetic depth scene) or false; rcand has no depth camera driver yet");
    d.enabled = true;
  }
  d.zones.min_range_mm = own.get_or<int>("depth_min_range_mm", 200);
  d.zones.max_range_mm = own.get_or<int>("depth_max_range_mm", 4000);
  if (d.zones.min_range_mm >= d.zones.max_range_mm)
    throw ConfigError("runtime.capabilities.vision.depth_min_range_mm: must be below depth_max_range_mm");
  d.zones.min_blob_fraction = own.get_or<double>("depth_min_blob", 0.001);
  d.zones.roi_top = own.get_or<double>("depth_roi_top", 0.0);
  d.zones.roi_bottom = own.get_or<double>("depth_roi_bottom", 1.0);
  if (d.zones.roi_top >= d.zones.roi_bottom)
    throw ConfigError("runtime.capabilities.vision.depth_roi_top: must be above depth_roi_bottom");
  d.max_age = std::chrono::milliseconds(own.get_or<int>("depth_max_age_ms", 200));
  d.fps = own.get_or<double>("depth_fps", 15.0);
  return d;
}

}  // namespace

VisionSettings read_settings(const ConfigView& camera, const ConfigView& own) {
  VisionSettings v;
  v.source = read_source(camera, own);
  v.jpeg_quality = own.get_or<int>("jpeg_quality", 80);
  v.hub.max_viewers = static_cast<std::size_t>(own.get_or<int>("max_viewers", 32));
  v.hub.reserved_viewers = static_cast<std::size_t>(own.get_or<int>("reserved_viewers", 4));
  v.hub.signal_timeout = std::chrono::milliseconds(own.get_or<int>("signal_timeout_ms", 250));
  v.hub.width = v.source.width;
  v.hub.height = v.source.height;
  v.hub.source = std::string(kind_name(v.source.kind)) + (v.source.location.empty() ? "" : " " + redact_url(v.source.location));
  v.capture.reconnect_max = std::chrono::milliseconds(own.get_or<int>("reconnect_max_ms", 5000));
  v.depth = read_depth(camera, own);
  return v;
}

std::optional<double> parse_fps(std::string_view text, std::string& error) {
  double value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec == std::errc() && end == text.data() + text.size() && std::isfinite(value) && value >= Vision::kMinFps &&
      value <= Vision::kMaxFps)
    return value;
  error = "fps must be a number in [0.2, 120]: a stream offered no frame for 10 s is closed";
  return std::nullopt;
}

Vision::Vision(sdk::PluginContext& ctx, Encoder encoder, SourceFactory sources)
    : ctx_(ctx), settings_(read_settings(ctx.robot_config().sub("camera"), ctx.config())), sources_(std::move(sources)) {
  if (!encoder) encoder = jpeg_encoder(settings_.jpeg_quality);
  if (!sources_) sources_ = [source = settings_.source] { return make_source(source); };
  hub_ = std::make_shared<FrameHub>(settings_.hub, std::move(encoder), [&ctx](const sdk::Json& status) {
    ctx.publish_status(status);
    record_stream_metrics(ctx, status);
  });
  if (settings_.depth.enabled) depth_ = std::make_unique<DepthFeed>(settings_.depth);
}

Vision::~Vision() { shutdown(); }

void Vision::start() {
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);  // faults are reported by name, here
  declare_stream_metrics(ctx_);
  hub_->start();
  capture_ = std::make_unique<Capture>(sources_, settings_.capture, hub_, [&ctx = ctx_](bool fault, const std::string& text) {
    if (fault) ctx.log().error("camera: ", text);
    else ctx.log().info(text);
  });
  capture_->start();
  if (depth_) {
    depth_->start();
    if (!sdk::offer<sdk::ObstacleSource>(ctx_, *depth_))
      ctx_.log().warn("depth: another plugin is the robot's obstacle source; GET /api/depth/obstacles still answers");
  }
  ctx_.log().info("camera ", settings_.hub.source, ": up to ", settings_.hub.max_viewers, " viewers, JPEG quality ",
                  settings_.jpeg_quality);
}

void Vision::shutdown() noexcept {
  if (capture_ && !capture_->stop()) ctx_.log().warn("camera: the capture thread is stuck in the driver; left behind");
  capture_.reset();
  if (hub_) hub_->stop();
  if (depth_) depth_->stop();  // its offer was withdrawn before shutdown(); a reader would see it stale
}

void Vision::mjpeg(const sdk::Request& request, const std::shared_ptr<sdk::StreamWriter>& writer) {
  std::optional<double> max_fps;
  if (const auto fps = request.query.find("fps"); fps != request.query.end()) {
    std::string error;
    max_fps = parse_fps(fps->second, error);
    if (!max_fps) {
      writer->respond(sdk::Response::bad_request("fps", error));
      return;
    }
  }
  // The last reserved_viewers places are the operators' (OWNER, CREATOR; everyone in auth mode open), so guests
  // cannot lock the owner's dashboard out of the camera. rcand itself caps viewers per principal and per address.
  const bool operator_role = sdk::role_grants(request.role, sdk::Scope::Config);
  switch (hub_->add_viewer(writer, max_fps, request.principal, operator_role)) {
    case FrameHub::Admission::Admitted: return;
    case FrameHub::Admission::Gone:
      writer->respond(sdk::Response::error(503, "UNAVAILABLE", "the camera is shutting down"));
      return;
    case FrameHub::Admission::Reserved:
      writer->respond(sdk::Response::error(503, "SLOTS_RESERVED",
                                           "the remaining viewer places are reserved for OWNER and CREATOR principals "
                                           "(runtime.capabilities.vision.reserved_viewers)",
                                           {{"field", "reserved_viewers"}}),
                      {{"Retry-After", "5"}});
      return;
    case FrameHub::Admission::Full: break;
  }
  const auto limit = hub_->max_viewers();
  writer->respond(sdk::Response::error(503, "UNAVAILABLE",
                                       "viewer limit reached: " + std::to_string(limit) +
                                           " viewers watch already (runtime.capabilities.vision.max_viewers)",
                                       {{"limit", limit}, {"field", "max_viewers"}}),
                  {{"Retry-After", "5"}});
}

void Vision::snapshot(const sdk::Request&, const std::shared_ptr<sdk::StreamWriter>& writer) { hub_->add_snapshot(writer); }

std::vector<sdk::Route> Vision::routes() {
  std::vector<sdk::Route> routes{
      {"GET", "/api/depth/obstacles", sdk::Scope::Status, false, "", [this](const sdk::Request& r) { return obstacles(r); }}};
  // Only the synthetic scene can be told what to show; a real depth camera never gets this route.
  if (depth_)
    routes.push_back({"POST", "/api/depth/sim_obstacle", sdk::Scope::Control, false, "",
                      [this](const sdk::Request& r) { return sim_obstacle(r); }});
  return routes;
}

std::vector<sdk::StreamRoute> Vision::stream_routes() {
  return {{"GET", "/api/stream/mjpeg", sdk::Scope::Status,
           [this](const sdk::Request& request, std::shared_ptr<sdk::StreamWriter> writer) { mjpeg(request, writer); }},
          {"GET", "/api/stream/snapshot", sdk::Scope::Status,
           [this](const sdk::Request& request, std::shared_ptr<sdk::StreamWriter> writer) { snapshot(request, writer); }},
          {"GET", "/api/depth/frame", sdk::Scope::Status,
           [this](const sdk::Request& request, std::shared_ptr<sdk::StreamWriter> writer) { depth_frame(request, writer); }}};
}

// docs/protocol.md §7.9, from the cached zones (never waits for a frame).
sdk::Response Vision::obstacles(const sdk::Request&) const {
  if (!depth_) return sdk::Response::ok({{"available", false}, {"reason", "no depth source configured (camera.depth)"}});
  const Zones z = depth_->zones();
  if (!z.available) return sdk::Response::ok({{"available", false}, {"reason", z.reason}});
  return sdk::Response::ok({{"available", true},
                            {"left_cm", z.left_cm},
                            {"center_cm", z.center_cm},
                            {"right_cm", z.right_cm},
                            {"nearest_cm", z.nearest_cm},
                            {"timestamp_ms", z.timestamp_ms}});
}

// {"zone": "left" | "center" | "right", "distance_m": metres, or null to remove}. The object stays until removed. A
// frame showing it is fed before the answer, so the answer's zones are what nav and teleop read from then on, and
// fed_us (plugin clock, the one the sim drive's timeline uses) is when that frame was rendered: bench/ measures an
// obstacle stop from it.
sdk::Response Vision::sim_obstacle(const sdk::Request& request) {
  const auto& body = request.body;
  if (!body.is_object()) return sdk::Response::bad_request("body", "the body must be a JSON object");
  const auto zone_it = body.find("zone");
  const auto& zones = SyntheticScene::kZones;
  const auto zone = zone_it != body.end() && zone_it->is_string()
                        ? std::find(zones.begin(), zones.end(), zone_it->get<std::string>()) - zones.begin()
                        : static_cast<std::ptrdiff_t>(zones.size());
  if (zone == static_cast<std::ptrdiff_t>(zones.size()))
    return sdk::Response::bad_request("zone", "zone must be \"left\", \"center\" or \"right\"");
  const auto distance = body.find("distance_m");
  const bool removing = distance != body.end() && distance->is_null();
  if (!removing && (distance == body.end() || !distance->is_number() || !std::isfinite(distance->get<double>()) ||
                    distance->get<double>() < 0.0 || distance->get<double>() > 20.0))
    return sdk::Response::bad_request("distance_m", "distance_m must be a number of metres in [0, 20], or null to remove");
  depth_->scene().place(static_cast<int>(zone), removing ? std::nullopt : std::optional<double>(distance->get<double>()));
  const std::int64_t fed_us = ctx_.clock().now_us();
  depth_->refresh();
  ctx_.log().info("sim depth: ", zones[static_cast<std::size_t>(zone)],
                  removing ? " object removed" : " object placed at " + std::to_string(distance->get<double>()) + " m");
  sdk::Json placed = sdk::Json::object();
  const auto now = depth_->scene().placed();
  for (std::size_t i = 0; i < zones.size(); ++i) placed[std::string(zones[i])] = now[i] ? sdk::Json(*now[i]) : sdk::Json(nullptr);
  return sdk::Response::ok({{"ok", true}, {"placed", placed}, {"fed_us", fed_us}, {"obstacles", obstacles(request).body}});
}

// The latest depth frame, colour-mapped, encoded here on the capability's worker (no request thread, no capture).
void Vision::depth_frame(const sdk::Request&, const std::shared_ptr<sdk::StreamWriter>& writer) const {
  const auto frame = depth_ ? depth_->latest() : nullptr;
  sdk::SharedBytes jpeg;
  try {
    if (frame) jpeg = depth_jpeg(*frame, settings_.depth.zones, settings_.jpeg_quality);
  } catch (const JpegError& e) {
    ctx_.log().error("depth frame: ", e.what());
    writer->respond(sdk::Response::error(500, "INTERNAL", "the depth frame could not be encoded"));
    return;
  }
  if (!jpeg) {
    writer->respond(
        sdk::Response::error(503, "UNAVAILABLE", depth_ ? "no depth frame yet" : "no depth source configured (camera.depth)"));
    return;
  }
  if (writer->start(200, "image/jpeg", {{"Cache-Control", "no-store"}})) writer->send(jpeg);
}

}  // namespace rcand::plugins::vision
