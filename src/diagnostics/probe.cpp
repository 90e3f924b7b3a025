#include "diagnostics/probe.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/settings.hpp"
#include "collect/collect.hpp"
#include "collect/expert_episode.hpp"
#include "core/error.hpp"
#include "data/h5_episode.hpp"
#include "datasets/episode_set.hpp"
#include "inference/policy_runner.hpp"
#include "world/world.hpp"

namespace cd {

using nlohmann::json;

namespace {

struct Accumulator {
  ProbeGroup g;
  void add(double real, double moving, double still) {
    ++g.count;
    g.mean_real += real;
    g.mean_moving += moving;
    g.mean_static += still;
    g.history_effect += std::abs(moving - still);
    g.moving_minus_static += moving - still;
  }
  ProbeGroup mean() const {
    ProbeGroup m = g;
    if (m.count == 0) return m;
    const double n = static_cast<double>(m.count);
    m.mean_real /= n;
    m.mean_moving /= n;
    m.mean_static /= n;
    m.history_effect /= n;
    m.moving_minus_static /= n;
    return m;
  }
};

json group_json(const ProbeGroup& g) {
  auto value = [&](double v) { return g.count > 0 ? json(v) : json(nullptr); };
  return {{"count", g.count},
          {"mean_real", value(g.mean_real)},
          {"mean_moving", value(g.mean_moving)},
          {"mean_static", value(g.mean_static)},
          {"history_effect", value(g.history_effect)},
          {"moving_minus_static", value(g.moving_minus_static)}};
}

// Replays the episodes of a camera data folder: the collection is deterministic for an
// episode's seed, so the expert, its noise and the traffic drive them again as recorded.
class CameraReplay {
 public:
  explicit CameraReplay(const std::string& data) {
    const std::string manifest = data + "/collect.json";
    const std::optional<json> recorded = recorded_collect_settings(data);
    if (!recorded)
      throw DataError(manifest + " is missing: the camera's copycat probe replays the collected "
                      "episodes with the settings it records");
    settings_ = settings_from_json(*recorded, manifest);
    world_ = std::make_unique<World>(settings_);
  }

  // Drives the episode of `file` (of `frames` frames) again and calls at(world, t, recorded)
  // for each frame t of `at_frames` (ascending) while the world holds that frame's state;
  // `recorded` is frame t as the replay recorded it (C x H x W bytes).
  void run(const std::string& file, int frames, const std::vector<int>& at_frames,
           const std::function<void(const World&, int, const uint8_t*)>& at) {
    const EpisodeMeta meta = read_episode_meta(file);
    if (const auto driver = meta.extra.find("driver"); driver != meta.extra.end())
      throw DataError(file + " was driven by " + driver->second +
                      " (a DAgger rollout): the camera's copycat probe replays the expert's "
                      "episodes only");
    const auto index = meta.extra.find("episode_index");
    ExpertRecorder recorder(*world_, settings_);
    EpisodeData data;
    EpisodeMeta replayed;
    std::vector<uint8_t> frame;
    size_t next = 0;
    recorder.set_frame_observer([&](long t) {
      if (next >= at_frames.size() || at_frames[next] != t) return;
      frame.resize(data.frame_bytes());
      data.frame_planes(static_cast<size_t>(t), frame.data());
      at(*world_, at_frames[next++], frame.data());
    });
    const EpisodeSummary s = recorder.run(
        index == meta.extra.end() ? 0 : std::atoi(index->second.c_str()), meta.seed, data,
        replayed);
    if (s.frames != frames || s.outcome != meta.outcome)
      throw DataError("replaying " + file + " gave " + std::to_string(s.frames) + " frames, " +
                      s.outcome + ", where it holds " + std::to_string(frames) + ", " +
                      meta.outcome + ": the camera's copycat probe needs the replay");
  }

 private:
  Settings settings_;
  std::unique_ptr<World> world_;
};

}  // namespace

Pose2 pose_behind(const Pose2& pose, double metres) {
  Pose2 p = pose;
  p.pos.x -= metres * std::cos(pose.heading);
  p.pos.y -= metres * std::sin(pose.heading);
  return p;
}

void shift_frame_up(const unsigned char* current, int channels, int height, int width, int shift,
                    unsigned char* out) {
  const size_t row = static_cast<size_t>(width);
  shift = std::clamp(shift, 0, height);
  for (int c = 0; c < channels; ++c) {
    const unsigned char* src = current + static_cast<size_t>(c) * height * row;
    unsigned char* dst = out + static_cast<size_t>(c) * height * row;
    std::memcpy(dst, src + shift * row, (height - shift) * row);
    std::memset(dst + (height - shift) * row, 0, shift * row);
  }
}

ProbeReport run_probe(const ProbeOptions& o) {
  set_torch_threads(1);
  PolicyRunner policy(o.checkpoint);
  const Checkpoint& ck = policy.checkpoint();
  const int K = policy.history(), stride = policy.stride();
  if (K < 2)
    throw ConfigError("the copycat probe needs a history policy such as bc-oh; " + o.checkpoint +
                      " holds '" + ck.method + "', which sees " + std::to_string(K) + " frame");
  EpisodeSet set = load_episode_set(o.data);
  require_same_frames(set, ck.input, o.data);
  // The BEV's moving history moves its content ahead by metres per pixel; the camera's is the
  // scene drawn again from behind, on the collection's episodes replayed. MuJoCo-Image's
  // frames have neither.
  if (set.domain != kDrivingDomain)
    throw ConfigError("the copycat probe needs driving frames; " + o.data +
                      " holds MuJoCo-Image frames (not supported)");
  const bool camera = set.layout == FrameLayout::Bytes;

  ProbeReport r;
  r.checkpoint = o.checkpoint;
  r.data = o.data;
  r.method = ck.method;
  r.output = policy.target_speed_head() ? "target_speed" : "throttle_minus_brake";
  r.history = K;
  r.stride = stride;
  r.moving_speed = o.moving_speed;
  r.stopped_below = o.stopped_below;
  r.dt = set.dt;
  r.metres_per_pixel = set.metres_per_pixel;
  r.moving_history = camera ? "replayed" : "shifted";
  r.frames = set.total_frames();

  struct Candidate {
    int e, t;
  };
  std::vector<Candidate> stopped;  // in episode and frame order
  const int first = (K - 1) * stride;
  for (int e = 0; e < static_cast<int>(set.episodes.size()); ++e) {
    const PackedEpisode& ep = set.episodes[e];
    if (ep.path_free.empty())
      throw DataError("episode file " + o.data + "/" + ep.file +
                      " has no causes/path_free (record the data with `causaldrive collect`)");
    for (int t = first; t < ep.frames; ++t)
      if (ep.speed[t] < o.stopped_below) stopped.push_back({e, t});
  }
  r.stopped_frames = static_cast<long>(stopped.size());
  std::vector<Candidate> probed = stopped;
  if (o.max_frames > 0 && static_cast<size_t>(o.max_frames) < stopped.size()) {
    probed.clear();
    for (long i = 0; i < o.max_frames; ++i)
      probed.push_back(stopped[static_cast<size_t>(i) * stopped.size() / o.max_frames]);
  }
  r.probed_frames = static_cast<long>(probed.size());

  const size_t fv = set.frame_values();
  std::vector<uint8_t> real(fv * K), moving(fv * K);
  std::vector<const uint8_t*> real_ptr(K), moving_ptr(K), static_ptr(K);
  for (int k = 0; k < K; ++k) {
    real_ptr[k] = real.data() + k * fv;
    moving_ptr[k] = moving.data() + k * fv;
  }
  // The metres the ego would have driven from history slot k to now.
  auto lag_metres = [&](int k) { return o.moving_speed * (K - 1 - k) * stride * set.dt; };
  Accumulator free_acc, blocked_acc;
  // Frame t of episode e with its real history in `real` and its moving one in `moving`.
  auto probe_frame = [&](int e, int t) {
    const PackedEpisode& ep = set.episodes[e];
    const uint8_t* current = real.data() + (K - 1) * fv;
    for (int k = 0; k < K; ++k) static_ptr[k] = current;
    const double speed = ep.speed[t];
    const int command = ep.command[t];
    const double out_real = policy.run(real_ptr.data(), speed, command).scalar();
    const double out_moving = policy.run(moving_ptr.data(), speed, command).scalar();
    const double out_static = policy.run(static_ptr.data(), speed, command).scalar();
    (ep.path_free[t] >= 0.5f ? free_acc : blocked_acc).add(out_real, out_moving, out_static);
  };
  auto load_real = [&](int e, int t) {
    for (int k = 0; k < K; ++k) set.planes255(e, t - (K - 1 - k) * stride, real.data() + k * fv);
  };
  if (!camera) {
    for (const Candidate& c : probed) {
      load_real(c.e, c.t);
      const uint8_t* current = real.data() + (K - 1) * fv;
      for (int k = 0; k < K; ++k) {
        const int shift = static_cast<int>(std::lround(lag_metres(k) / set.metres_per_pixel));
        shift_frame_up(current, set.channels, set.height, set.width, shift,
                       moving.data() + k * fv);
      }
      probe_frame(c.e, c.t);
    }
  } else {
    CameraReplay replay(o.data);
    size_t i = 0;
    while (i < probed.size()) {
      const int e = probed[i].e;
      std::vector<int> frames;
      for (; i < probed.size() && probed[i].e == e; ++i) frames.push_back(probed[i].t);
      const std::string file = o.data + "/" + set.episodes[e].file;
      const PackedEpisode& ep = set.episodes[e];
      replay.run(file, ep.frames, frames, [&](const World& world, int t, const uint8_t* drawn) {
        load_real(e, t);
        if (std::memcmp(drawn, real.data() + (K - 1) * fv, fv) != 0)
          throw DataError("replaying " + file + " drew frame " + std::to_string(t) +
                          " otherwise than it was recorded (another build, or settings other "
                          "than collect.json's): the camera's copycat probe needs the replay");
        // The pose the frame was drawn from: the ego's, or collect.augment's shifted one.
        const size_t a = 2 * static_cast<size_t>(t);
        const Pose2 seen = ep.augment.empty() ? world.ego().pose
                                              : shifted_pose(world.ego().pose, ep.augment[a],
                                                             ep.augment[a + 1]);
        for (int k = 0; k < K; ++k)
          world.render_from(pose_behind(seen, lag_metres(k)), moving.data() + k * fv);
        probe_frame(e, t);
      });
      ++r.replayed_episodes;
    }
  }
  r.path_free = free_acc.mean();
  r.blocked = blocked_acc.mean();
  return r;
}

json probe_report_json(const ProbeReport& r) {
  return {{"checkpoint", r.checkpoint},
          {"data", r.data},
          {"method", r.method},
          {"history", r.history},
          {"history_stride", r.stride},
          {"output", r.output},
          {"moving_speed", r.moving_speed},
          {"moving_history", r.moving_history},
          {"replayed_episodes", r.replayed_episodes},
          {"stopped_below", r.stopped_below},
          {"frames", r.frames},
          {"stopped_frames", r.stopped_frames},
          {"probed_frames", r.probed_frames},
          {"path_free", group_json(r.path_free)},
          {"blocked", group_json(r.blocked)}};
}

std::string probe_report_table(const ProbeReport& r) {
  char buf[768];
  std::string s;
  const std::string how = r.moving_history == "replayed"
                              ? "the scene drawn from behind on " +
                                    std::to_string(r.replayed_episodes) + " replayed episodes"
                              : "the view shifted";
  std::snprintf(buf, sizeof buf,
                "copycat probe: %s (history %d, stride %d) on %s\n"
                "output: %s; moving history at %.1f m/s, %s\n"
                "stopped frames (speed < %.2f m/s, full history): %ld of %ld, probed %ld\n\n",
                r.method.c_str(), r.history, r.stride, r.data.c_str(),
                r.output == "target_speed" ? "target speed (m/s)" : "throttle - brake",
                r.moving_speed, how.c_str(), r.stopped_below, r.stopped_frames, r.frames, r.probed_frames);
  s += buf;
  std::snprintf(buf, sizeof buf, "%-10s %7s %9s %9s %9s %16s\n", "path", "frames", "real",
                "moving", "static", "|moving-static|");
  s += buf;
  auto row = [&](const char* name, const ProbeGroup& g) {
    if (g.count == 0)
      std::snprintf(buf, sizeof buf, "%-10s %7ld %9s %9s %9s %16s\n", name, g.count, "-", "-",
                    "-", "-");
    else
      std::snprintf(buf, sizeof buf, "%-10s %7ld %9.3f %9.3f %9.3f %16.3f\n", name, g.count,
                    g.mean_real, g.mean_moving, g.mean_static, g.history_effect);
    s += buf;
  };
  row("free", r.path_free);
  row("blocked", r.blocked);
  return s;
}

}  // namespace cd
