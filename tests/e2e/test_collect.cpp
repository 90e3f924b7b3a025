// Expert data collection through the real CLI: files and their layout (checked with h5py),
// determinism, resuming after the whole process group was killed, PNG frames.
// needs: sumo
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../support/tiny_run.hpp"
#include "collect/collect.hpp"
#include "core/error.hpp"
#include "core/run_lock.hpp"
#include "data/h5_episode.hpp"

namespace cd {
namespace {

using test::CommandResult;
using test::TempDir;

bool is_episode_name(const std::string& name) {
  return test::starts_with(name, "episode_") && test::ends_with(name, ".h5");
}

std::vector<std::string> episode_files(const std::string& dir) {
  std::vector<std::string> out;
  for (const auto& n : test::list_dir(dir))
    if (is_episode_name(n)) out.push_back(n);
  return out;
}

std::vector<std::string> tmp_files(const std::string& dir) {
  std::vector<std::string> out;
  for (const auto& n : test::list_dir(dir))
    if (test::ends_with(n, ".tmp")) out.push_back(n);
  return out;
}

CommandResult collect_cli(const std::string& config, const std::string& out, int episodes,
                          int workers, const std::vector<std::string>& more = {}) {
  return test::run_cli(test::collect_args(
      config, out,
      test::with({"--episodes", std::to_string(episodes), "--workers", std::to_string(workers)},
                 more)));
}

// The h5py oracle: shapes and types of one or more episode files (SPEC section 2).
const char* kLayoutScript = R"PY(
import sys
import h5py
import numpy as np

for path in sys.argv[1:]:
    with h5py.File(path, "r") as f:
        for name in ["bev", "speed", "action", "command", "pose"]:
            assert name in f, f"{path}: dataset {name} missing"
        assert "causes" in f and isinstance(f["causes"], h5py.Group), f"{path}: causes/ missing"
        T = f["speed"].shape[0]
        assert T > 0, f"{path}: no frames"
        lengths = {name: f[name].shape[0] for name in ["bev", "speed", "action", "command", "pose"]}
        causes = list(f["causes"].keys())
        assert len(causes) > 0, f"{path}: causes/ is empty"
        for c in causes:
            lengths["causes/" + c] = f["causes"][c].shape[0]
        assert all(n == T for n in lengths.values()), f"{path}: first dimensions differ: {lengths}"
        bev = f["bev"]
        assert bev.dtype == np.uint8, f"{path}: bev is {bev.dtype}"
        assert bev.ndim == 4, f"{path}: bev has {bev.ndim} dims"
        assert f["speed"].dtype == np.float32 and f["speed"].ndim == 1
        assert f["action"].dtype == np.float32 and f["action"].ndim == 2
        assert f["command"].dtype == np.int32 and f["command"].ndim == 1
        assert f["pose"].dtype == np.float32 and f["pose"].shape == (T, 3)
        for attr in ["town", "seed", "dt", "format_version", "suite", "channels",
                     "metres_per_pixel"]:
            assert attr in f.attrs, f"{path}: attribute {attr} missing"
        town = f.attrs["town"]
        town = town.decode() if isinstance(town, bytes) else str(town)
        assert town == "town-a", f"{path}: town {town!r}"
        assert abs(float(f.attrs["dt"]) - 0.1) < 1e-9, f"{path}: dt {f.attrs['dt']}"
        assert bev.shape[1] == len(f.attrs["channels"]), f"{path}: channels do not match bev"
        frame = bev[T - 1]
        assert set(np.unique(frame)).issubset({0, 255}), f"{path}: bev values {np.unique(frame)}"
        assert frame.max() == 255, f"{path}: an empty frame"
        speed = f["speed"][:]
        assert np.all(speed >= 0) and np.all(np.isfinite(speed)), f"{path}: bad speeds"
        action = f["action"][:]
        names = [n.decode() if isinstance(n, bytes) else str(n) for n in f.attrs["action_names"]]
        # The default ego steers (ego.lateral = "free"): throttle, brake in [0,1], steer in [-1,1].
        assert names == ["throttle", "brake", "steer"], f"{path}: action_names {names}"
        assert action.shape == (T, 3), f"{path}: action shape {action.shape}"
        assert np.all((action[:, :2] >= 0) & (action[:, :2] <= 1)), f"{path}: pedals outside [0,1]"
        assert np.all(np.abs(action[:, 2]) <= 1), f"{path}: steer outside [-1,1]"
        assert np.abs(action[:, 2]).max() > 0.05, f"{path}: the expert never steered"
        # The causes agree with each other and with the documented codes.
        c = {name: f["causes"][name][:] for name in causes}
        assert sorted(causes) == ["junction_distance", "lead_distance", "lead_present",
                                  "lead_speed", "must_yield", "path_free", "ped_distance",
                                  "ped_on_path", "tl_distance", "tl_state"], causes
        for flag in ["lead_present", "must_yield", "path_free", "ped_on_path"]:
            assert set(np.unique(c[flag])).issubset({0.0, 1.0}), f"{path}: {flag} not 0/1"
        assert set(np.unique(c["tl_state"])).issubset({0.0, 1.0, 2.0, 3.0, 4.0})
        assert np.all(c["lead_distance"][c["lead_present"] == 0] == 100.0)
        assert np.all(c["lead_distance"][c["lead_present"] == 1] < 100.0)
        assert np.all(c["tl_distance"][c["tl_state"] == 0] == 100.0)
        assert np.all(c["ped_distance"][c["ped_on_path"] == 0] == 100.0)
        # A red light close ahead always blocks the path.
        red_close = (c["tl_state"] == 1) & (c["tl_distance"] < 3.0)
        assert np.all(c["path_free"][red_close] == 0), f"{path}: red light but path free"
        # Commands are the documented codes, and speed changes match the time step's limits.
        assert set(np.unique(f["command"][:])).issubset({0, 1, 2, 3})
        assert np.all(np.abs(np.diff(speed)) <= 0.1 * 8.0 + 1e-4), f"{path}: speed jumps"
    print("ok", path)
)PY";

TEST(Collect, WritesEpisodesWithTheDatasetLayout) {
  TempDir dir("cdtest-collect");
  const std::string config = test::write_test_config(dir, "regular");
  const std::string out = dir / "data";
  CommandResult r = collect_cli(config, out, 2, 2);
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  EXPECT_TRUE(test::starts_with(r.out, "episodes in")) << r.out;
  EXPECT_NE(r.out.find("recorded now: 2"), std::string::npos) << r.out;

  std::vector<std::string> names = test::list_dir(out);
  EXPECT_EQ(names, (std::vector<std::string>{"causaldrive.lock", "collect.json",
                                             "episode_000000.h5", "episode_000001.h5"}));
  CommandResult py = test::run_python(kLayoutScript,
                                      {out + "/episode_000000.h5", out + "/episode_000001.h5"}, dir);
  EXPECT_TRUE(py.exited && py.exit_code == 0) << py.describe();

  // The C++ reader agrees.
  for (int i = 0; i < 2; ++i) {
    EpisodeMeta meta;
    EpisodeData d = read_episode(out + "/" + episode_file_name(i), &meta);
    EXPECT_GT(d.frames(), 0u);
    EXPECT_EQ(meta.town, "town-a");
    EXPECT_EQ(meta.dt, 0.1);
    EXPECT_FALSE(meta.outcome.empty());
  }

  nlohmann::json manifest = nlohmann::json::parse(test::read_text(out + "/collect.json"));
  ASSERT_TRUE(manifest.contains("episodes"));
  ASSERT_EQ(manifest["episodes"].size(), 2u);
  EXPECT_EQ(manifest["episodes"][0]["file"], "episode_000000.h5");
  EXPECT_EQ(manifest["episodes"][1]["file"], "episode_000001.h5");
  ASSERT_TRUE(manifest.contains("settings"));
  EXPECT_EQ(manifest["settings"]["world"]["traffic"], "regular");
  EXPECT_EQ(manifest["settings"]["collect"]["episodes"], 2);
  EXPECT_EQ(manifest["settings"]["collect"]["out"], out);
}

// A free-steering ego (issue 13, the default) and a route-mode one: the config's extra table,
// and what their data must hold.
const char* kFreeSteering = "\n[ego]\nlateral = \"free\"\n";
const char* kRouteMode = "\n[ego]\nlateral = \"route\"\n";

void expect_deterministic_and_seed_dependent(const std::string& extra,
                                             const std::vector<std::string>& more) {
  TempDir dir("cdtest-collect");
  const std::string config = test::write_test_config(dir, "regular", extra);
  const std::string a = dir / "a", b = dir / "b", c = dir / "c", d = dir / "d";
  CommandResult ra = collect_cli(config, a, 2, 2, more);
  CommandResult rb = collect_cli(config, b, 2, 2, more);
  CommandResult rc = collect_cli(config, c, 2, 1, more);  // the worker count changes nothing
  CommandResult rd = collect_cli(config, d, 2, 2, test::with({"--seed", "7"}, more));
  for (const CommandResult* r : {&ra, &rb, &rc, &rd})
    ASSERT_TRUE(r->exited && r->exit_code == 0) << r->describe();
  for (int i = 0; i < 2; ++i) {
    const std::string name = episode_file_name(i);
    const std::string fa = test::read_text(a + "/" + name);
    ASSERT_FALSE(fa.empty());
    EXPECT_TRUE(fa == test::read_text(b + "/" + name)) << name << " differs between two runs";
    EXPECT_TRUE(fa == test::read_text(c + "/" + name)) << name << " depends on --workers";
    EXPECT_FALSE(fa == test::read_text(d + "/" + name)) << name << " ignores --seed";
  }
  auto episodes = [](const std::string& folder) {
    return nlohmann::json::parse(test::read_text(folder + "/collect.json"))["episodes"];
  };
  EXPECT_EQ(episodes(a), episodes(b));
  EXPECT_NE(episodes(a), episodes(d));
  EpisodeMeta meta;
  const EpisodeData first = read_episode(a + "/" + episode_file_name(0), &meta);
  const bool free = extra == kFreeSteering;
  EXPECT_EQ(first.action_dim, free ? 3 : 2);
  EXPECT_EQ(meta.action_names.size(), static_cast<size_t>(first.action_dim));
  if (free) {
    EXPECT_EQ(meta.action_names.back(), "steer");
    double most = 0;
    for (size_t t = 0; t < first.frames(); ++t) most = std::max(most, std::abs(double(first.action[t * 3 + 2])));
    EXPECT_GT(most, 0.05) << "the expert never steered";
  }
}

TEST(Collect, IsDeterministicAndSeedDependent) {
  expect_deterministic_and_seed_dependent(kRouteMode, {});
}

TEST(CollectSteering, IsDeterministicAndSeedDependentWithSteerNoise) {
  // town-c: two lanes per direction, so the free ego changes lanes where its route needs it.
  expect_deterministic_and_seed_dependent(kFreeSteering, {"--noise", "--town", "town-c"});
}

void expect_resume_after_kill(const std::string& extra) {
  TempDir dir("cdtest-collect");
  const std::string config = test::write_test_config(dir, "regular", extra);
  const int kEpisodes = 6;
  const std::string out = dir / "data", ref = dir / "ref";
  const std::vector<std::string> argv = {CD_BINARY, "collect", "--config", config,
                                         "--episodes", std::to_string(kEpisodes),
                                         "--workers", "1", "--out", out};

  // kill -9 of the command and its workers right after episode 1 is committed (the hook of
  // core/fault.hpp; its marker file stays in the folder).
  {
    test::ScopedEnv crash("CAUSALDRIVE_INJECT_CRASH", "collect:1");
    CommandResult killed = test::run_command(argv);
    ASSERT_TRUE(!killed.exited && killed.signal == SIGKILL) << killed.describe();
  }
  const std::vector<std::string> after_kill = episode_files(out);
  EXPECT_EQ(after_kill, (std::vector<std::string>{episode_file_name(0), episode_file_name(1)}));
  for (const std::string& name : test::list_dir(out)) {
    if (is_episode_name(name)) {
      EXPECT_NO_THROW(read_episode(out + "/" + name)) << name << " is incomplete";
    } else {
      // The killed job's lock file stays (its flock died with it): the next job takes it over.
      EXPECT_TRUE(test::ends_with(name, ".tmp") || name == ".crash-injected-collect-1" ||
                  name == kRunLockName)
          << "unexpected leftover " << name;
    }
  }

  CommandResult resumed = test::run_cli(std::vector<std::string>(argv.begin() + 1, argv.end()));
  ASSERT_TRUE(resumed.exited && resumed.exit_code == 0) << resumed.describe();
  EXPECT_NE(resumed.out.find("recorded now: " + std::to_string(kEpisodes - after_kill.size())),
            std::string::npos)
      << resumed.out;
  EXPECT_EQ(episode_files(out).size(), static_cast<size_t>(kEpisodes));
  EXPECT_TRUE(tmp_files(out).empty()) << "temporary files left after the resumed run";
  EXPECT_NE(resumed.err.find("taking over the lock of collect (host "), std::string::npos)
      << resumed.err;
  EXPECT_TRUE(test::lock_released(out)) << "released at the end";

  CommandResult whole = collect_cli(config, ref, kEpisodes, 1);
  ASSERT_TRUE(whole.exited && whole.exit_code == 0) << whole.describe();
  for (int i = 0; i < kEpisodes; ++i) {
    const std::string name = episode_file_name(i);
    EXPECT_TRUE(test::read_text(out + "/" + name) == test::read_text(ref + "/" + name))
        << name << " of the resumed run differs from the uninterrupted run";
  }

  // A complete folder: nothing to record, nothing changed.
  const std::string before = test::read_text(out + "/" + episode_file_name(0));
  CommandResult again = test::run_cli(std::vector<std::string>(argv.begin() + 1, argv.end()));
  ASSERT_TRUE(again.exited && again.exit_code == 0) << again.describe();
  EXPECT_NE(again.out.find("recorded now: 0"), std::string::npos) << again.out;
  EXPECT_EQ(episode_files(out).size(), static_cast<size_t>(kEpisodes));
  EXPECT_TRUE(test::read_text(out + "/" + episode_file_name(0)) == before);
}

TEST(Collect, ResumesAfterTheProcessGroupWasKilled) { expect_resume_after_kill(kRouteMode); }

TEST(CollectSteering, ResumesAfterTheProcessGroupWasKilled) {
  expect_resume_after_kill(kFreeSteering);
}

TEST(Collect, DamagedEpisodeFileIsRecordedAgain) {
  TempDir dir("cdtest-collect");
  const std::string config = test::write_test_config(dir, "empty");
  const std::string out = dir / "data";
  CommandResult r = collect_cli(config, out, 2, 1);
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  const std::string good = test::read_text(out + "/" + episode_file_name(1));
  test::write_text(out + "/" + episode_file_name(1), good.substr(0, good.size() / 2));
  test::write_text(out + "/" + episode_file_name(0) + ".12345.tmp", "leftover");
  r = collect_cli(config, out, 2, 1);
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  EXPECT_NE(r.out.find("recorded now: 1"), std::string::npos) << r.out;
  EXPECT_TRUE(test::read_text(out + "/" + episode_file_name(1)) == good);
  EXPECT_TRUE(tmp_files(out).empty());
}

TEST(Collect, PngFramesAreWritten) {
  TempDir dir("cdtest-collect");
  // A short episode (at most 8 s): one PNG per frame.
  const std::string config = test::write_test_config(dir, "empty", "max_episode_s = 8\n");
  const std::string out = dir / "data", png = dir / "png";
  CommandResult r = collect_cli(config, out, 1, 1, {"--png", png});
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  EpisodeData d = read_episode(out + "/" + episode_file_name(0));
  ASSERT_GT(d.frames(), 0u);

  std::vector<std::string> pngs;
  for (const auto& e : test::fs::recursive_directory_iterator(png))
    if (e.is_regular_file() && e.path().extension() == ".png") pngs.push_back(e.path().string());
  std::sort(pngs.begin(), pngs.end());
  ASSERT_FALSE(pngs.empty()) << "no PNG under " << png;
  EXPECT_EQ(pngs.size(), d.frames()) << "one PNG per recorded frame";
  const std::string signature = "\x89PNG\r\n\x1a\n";
  for (size_t i : {size_t(0), pngs.size() / 2, pngs.size() - 1}) {
    std::string bytes = test::read_text(pngs[i]);
    ASSERT_GE(bytes.size(), 33u) << pngs[i];
    EXPECT_EQ(bytes.substr(0, 8), signature) << pngs[i];
    EXPECT_EQ(bytes.substr(12, 4), "IHDR") << pngs[i];
  }
}

}  // namespace
}  // namespace cd

namespace cd {
namespace {

// collect.hold_s: the ego stands braked for the first steps while the expert's labels (go) are
// recorded and marked as not its motion; then the expert drives as without the hold.
TEST(Collect, HoldKeepsTheEgoStillWithTheExpertsLabels) {
  TempDir dir("cdtest-collect-hold");
  const std::string config =
      test::write_test_config(dir, "empty", std::string("max_episode_s = 8\nhold_s = 1.0\n") + kRouteMode);
  const std::string out = dir / "data";
  CommandResult r = collect_cli(config, out, 1, 1);
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  EpisodeData d = read_episode(out + "/" + episode_file_name(0));
  ASSERT_GT(d.frames(), 30u);
  // Steps 0..9 (1 s at 0.1 s) execute the brake: the ego has not moved by step 10, and the
  // expert's label is to go (full throttle from a standstill).
  for (size_t t = 0; t <= 10; ++t) EXPECT_EQ(d.speed[t], 0.0f) << "step " << t;
  for (size_t t = 0; t < 10; ++t) {
    EXPECT_EQ(d.noise[t], 1) << "step " << t;
    EXPECT_GT(d.action[2 * t], 0.5f) << "step " << t << ": the label is not to go";
    EXPECT_EQ(d.action[2 * t + 1], 0.0f) << "step " << t;
  }
  EXPECT_EQ(d.noise[10], 0);
  EXPECT_GT(d.speed[11], 0.0f) << "the expert did not start after the hold";
  // Same seed, same bytes.
  const std::string again = dir / "again";
  ASSERT_EQ(collect_cli(config, again, 1, 1).exit_code, 0);
  EXPECT_TRUE(test::read_text(out + "/" + episode_file_name(0)) ==
              test::read_text(again + "/" + episode_file_name(0)));
}

// A finished folder collected with other settings is not added to (its episodes and new ones
// would mix two datasets); the same settings with more episodes grow it.
TEST(Collect, AFolderOfOtherSettingsIsNotAddedTo) {
  TempDir dir("cdtest-collect-other"), other("cdtest-collect-other-b");
  const std::string a = test::write_test_config(dir, "empty", "max_episode_s = 8\nhold_s = 0.0\n");
  const std::string b = test::write_test_config(other, "empty", "max_episode_s = 8\nhold_s = 1.0\n");
  const std::string out = dir / "data";
  ASSERT_EQ(collect_cli(a, out, 1, 1).exit_code, 0);
  const std::string manifest = test::read_text(out + "/collect.json");
  CommandResult r = collect_cli(b, out, 2, 1);
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  ASSERT_EQ(test::split_lines(r.err).size(), 1u) << r.err;
  EXPECT_NE(r.err.find("collect.hold_s"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("another --out folder"), std::string::npos) << r.err;
  EXPECT_EQ(episode_files(out).size(), 1u);
  EXPECT_EQ(test::read_text(out + "/collect.json"), manifest);
  r = collect_cli(a, out, 2, 1);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_EQ(episode_files(out).size(), 2u);

  // A record written before some keys existed (here without the sense table and
  // collect.augment.cameras) reads them as their defaults: the folder is added to.
  nlohmann::json rec = nlohmann::json::parse(test::read_text(out + "/collect.json"));
  rec["settings"].erase("sense");
  rec["settings"]["collect"]["augment"].erase("cameras");
  test::write_text(out + "/collect.json", rec.dump(2));
  r = collect_cli(a, out, 3, 1);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_EQ(episode_files(out).size(), 3u);
  // The camera's episodes are not added to a folder of the BEV's.
  const std::string cam = test::write_test_config(
      other, "empty", "max_episode_s = 8\nhold_s = 0.0\n[sense]\nview = \"camera\"\n", "cam.toml");
  r = collect_cli(cam, out, 4, 1);
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  ASSERT_EQ(test::split_lines(r.err).size(), 1u) << r.err;
  EXPECT_NE(r.err.find("sense.view \"bev\" -> \"camera\""), std::string::npos) << r.err;
  EXPECT_EQ(episode_files(out).size(), 3u);
  // A damaged record is named, and the folder is left as it is.
  test::write_text(out + "/collect.json", "{\"settings\": ");
  r = collect_cli(a, out, 4, 1);
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  ASSERT_EQ(test::split_lines(r.err).size(), 1u) << r.err;
  EXPECT_NE(r.err.find("collect.json is damaged"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("another --out folder"), std::string::npos) << r.err;
  EXPECT_EQ(episode_files(out).size(), 3u);
  EXPECT_EQ(test::read_text(out + "/collect.json"), "{\"settings\": ");
}

}  // namespace
}  // namespace cd
