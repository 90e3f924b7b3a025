// needs: sumo
// The front camera through the binary (sense.view = "camera", SPEC section 16): collect records
// the camera's RGB frames as the HDF5 dataset "frames" (T, 3, H, W) uint8, chunked and deflated,
// which h5py reads, the same bytes for the same seed; bc-oh trains on them and drives in the simulator, with the same bytes
// whatever the worker count; an evaluation with the BEV refuses the camera's checkpoint (and
// the other way round) in one line, as it refuses the BEV's perception noise on the camera.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../support/tiny_run.hpp"

#ifndef CD_PYTHON
#define CD_PYTHON "/usr/bin/python3"
#endif

namespace cd {
namespace {

using nlohmann::json;

// A small camera (the default is 288 x 80) keeps the tiny run quick.
const std::string kCamera =
    "\n[sense]\nview = \"camera\"\n\n[sense.camera]\nwidth = 96\nheight = 32\n";
const std::string kTrain = "\n[train]\nepochs = 1\nmax_samples = 200\nthreads = 1\n"
                           "\n[ego]\nlateral = \"route\"\n";

TEST(CameraView, CollectTrainEvalAndTheViewOfACheckpoint) {
  CD_NEEDS_SUMO();
  test::TinyRun run({.method = "bc-oh",
                     .traffic = "regular",
                     .extra = kCamera + kTrain,
                     .suite = {.traffic = "empty", .scenarios = {"route"}}});

  // The recorded frames, read by h5py: "frames" in place of "bev", RGB that is not only 0/255
  // (the BEV's values), one frame per chunk, deflated, the view in the attributes.
  const std::string first = run.data() + "/episode_000000.h5";
  const std::string oracle = run.dir() / "oracle.py";
  test::write_text(oracle, R"PY(
import sys
import h5py
import numpy as np
with h5py.File(sys.argv[1], "r") as f:
    assert "bev" not in f and "frames" in f, sorted(f.keys())
    x = f["frames"]
    T = f["speed"].shape[0]
    assert x.dtype == np.uint8 and x.shape == (T, 3, 32, 96), (x.dtype, x.shape)
    assert x.chunks == (1, 3, 32, 96) and x.compression == "gzip", (x.chunks, x.compression)
    v = x[...]
    assert len(np.unique(v)) > 16, "RGB shading, not 0/255 planes"
    assert v[:, :, :8, :].mean() > v[:, :, -8:, :].mean() - 255, "an image"
    names = [n.decode() if isinstance(n, bytes) else str(n) for n in f.attrs["channels"]]
    assert names == ["red", "green", "blue"], names
    view = f.attrs["view"]
    assert (view.decode() if isinstance(view, bytes) else str(view)) == "camera", view
    weather = f.attrs["weather"]
    weather = weather.decode() if isinstance(weather, bytes) else str(weather)
    assert weather in ("clear-noon", "wet-noon", "hard-rain-noon", "clear-sunset"), weather
)PY");
  const test::CommandResult py =
      test::run_command({CD_PYTHON, oracle, first});
  ASSERT_TRUE(py.exited && py.exit_code == 0) << py.describe();
  // Same seed, same bytes.
  test::run_cli_ok(test::collect_args(run.config(), run.dir() / "again"));
  for (const char* f : {"episode_000000.h5", "episode_000001.h5"})
    EXPECT_EQ(test::read_text(run.data() + "/" + f), test::read_text(run.dir() / (std::string("again/") + f)))
        << f;

  // The checkpoint records the camera's input; its agent drives, the same bytes at 1 and 2
  // workers.
  const json input = test::read_json(run.run() + "/checkpoint.json")["input"];
  EXPECT_EQ(input["channels"], 3);
  EXPECT_EQ(input["height"], 32);
  EXPECT_EQ(input["width"], 96);
  EXPECT_EQ(input["channel_names"], json({"red", "green", "blue"}));
  run.eval("one", 1);
  run.eval("two", 2);
  const json res = run.results("one");
  ASSERT_EQ(res["episodes"].size(), 1u);
  EXPECT_EQ(res["summary"]["infrastructure_failures"], 0);
  // The default weather is the training pool; each episode names the set it drew.
  const std::string trained_in = res["episodes"][0].value("weather", "");
  EXPECT_TRUE(trained_in == "clear-noon" || trained_in == "wet-noon" ||
              trained_in == "hard-rain-noon" || trained_in == "clear-sunset")
      << res["episodes"][0].dump();
  // Table 8's new weather for the camera: the held-out pool, the same checkpoint.
  const std::string held = test::write_test_config(
      run.dir(), "empty", kTrain + kCamera + "weather = \"held-out\"\n", "held.toml");
  test::run_cli_ok(test::eval_args(held, "bc-oh", run.run(), run.suite(), run.dir() / "held", 1));
  const json new_weather = test::read_json(run.dir() / "held/results.json")["episodes"][0];
  EXPECT_TRUE(new_weather.value("weather", "") == "soft-rain-sunset" ||
              new_weather.value("weather", "") == "after-rain-dusk")
      << new_weather.dump();
  // The run records its weather setting (report's column); a folder of one weather is never
  // resumed in another, so a run's episodes never mix two weathers.
  EXPECT_EQ(res.value("weather", ""), "train") << res.dump();
  EXPECT_EQ(test::read_json(run.dir() / "held/results.json").value("weather", ""), "held-out");
  const test::CommandResult mixed = test::run_cli(
      test::eval_args(held, "bc-oh", run.run(), run.suite(), run.dir() / "one", 1));
  EXPECT_NE(mixed.exit_code, 0) << mixed.describe();
  EXPECT_NE(mixed.err.find("holds another evaluation (weather \"train\", now \"held-out\")"),
            std::string::npos)
      << mixed.err;
  EXPECT_EQ(test::read_text(run.dir() / "one/results.json"),
            test::read_text(run.dir() / "two/results.json"));

  // What the tools draw of camera frames: attention's grid (frame | map | overlay) at the
  // camera's size, its frame panel in the camera's colours (many, not the BEV's few); diagnose
  // compares on the folder; the report's replay of a recorded episode embeds its frames.
  test::run_cli_ok({"attention", "--checkpoint", run.run(), "--data", run.data(), "--out",
                    run.dir() / "att", "--frames", "2", "--select", "all", "--scale", "2"});
  const json att = test::read_json(run.dir() / "att/attention.json");
  ASSERT_EQ(att["frames"].size(), 2u) << att.dump();
  const std::string att_oracle = run.dir() / "att.py";
  test::write_text(att_oracle, R"PY(
import sys, zlib, struct
data = open(sys.argv[1], "rb").read()
w, h = struct.unpack(">II", data[16:24])
assert (w, h) == (3 * 96 * 2 + 2 * 2, 32 * 2), (w, h)
)PY");
  const test::CommandResult apy = test::run_command(
      {CD_PYTHON, att_oracle, run.dir() / ("att/" + att["frames"][0]["png"].get<std::string>())});
  ASSERT_TRUE(apy.exited && apy.exit_code == 0) << apy.describe();
  const test::CommandResult diag =
      test::run_cli_ok({"diagnose", "--checkpoint", run.run(), "--data", run.data(), "--json"});
  EXPECT_GT(json::parse(diag.out)["frames"].get<int>(), 0) << diag.out;
  // The probe's moving history on the camera: the folder's episodes replayed and the scene
  // drawn again from behind the ego. At 0 m/s the moving frames are the recorded frame (the
  // replay is checked against it byte for byte), so the history effect is exactly 0; at 5 m/s
  // the frames differ and so does the output.
  auto probe = [&](const std::string& data, const std::string& speed) {
    return test::run_cli({"probe", "--checkpoint", run.run(), "--data", data, "--moving-speed",
                          speed, "--max-frames", "6", "--json"});
  };
  auto effect = [](const json& p) {
    double sum = 0;
    for (const char* g : {"path_free", "blocked"})
      if (p[g]["count"].get<long>() > 0) sum += p[g]["history_effect"].get<double>();
    return sum;
  };
  const test::CommandResult still = probe(run.data(), "0");
  ASSERT_EQ(still.exit_code, 0) << still.describe();
  const json p0 = json::parse(still.out);
  EXPECT_EQ(p0["moving_history"], "replayed") << still.out;
  EXPECT_GE(p0["replayed_episodes"].get<long>(), 1) << still.out;
  EXPECT_GT(p0["probed_frames"].get<long>(), 0) << still.out;
  EXPECT_EQ(effect(p0), 0.0) << still.out;
  const test::CommandResult moving = probe(run.data(), "5");
  ASSERT_EQ(moving.exit_code, 0) << moving.describe();
  EXPECT_GT(effect(json::parse(moving.out)), 0.0) << moving.out;
  // A free-mode folder with every frame drawn from collect.augment's shifted pose: the moving
  // history stands behind that pose, so at 0 m/s it is again the recorded frame.
  const std::string free_config = test::write_test_config(
      run.dir(), "regular",
      kCamera + "\n[ego]\nlateral = \"free\"\n\n[collect.augment]\nfraction = 1.0\n",
      "free.toml");
  const std::string free_data = run.dir() / "free-data";
  test::run_cli_ok(test::collect_args(free_config, free_data));
  const test::CommandResult shifted = probe(free_data, "0");
  ASSERT_EQ(shifted.exit_code, 0) << shifted.describe();
  EXPECT_GT(json::parse(shifted.out)["probed_frames"].get<long>(), 0) << shifted.out;
  EXPECT_EQ(effect(json::parse(shifted.out)), 0.0) << shifted.out;
  // A folder whose record no longer gives its episodes (the expert's cruise speed changed), and
  // one without its record, are refused in one line.
  const std::filesystem::path copy = run.dir() / "data-copy";
  std::filesystem::copy(run.data(), copy);
  json manifest = test::read_json(copy / "collect.json");
  manifest["settings"]["expert"]["cruise_speed"] = 6.0;
  test::write_text(copy / "collect.json", manifest.dump());
  test::expect_one_line_error(probe(copy, "5"), "the camera's copycat probe needs the replay");
  std::filesystem::remove(copy / "collect.json");
  test::expect_one_line_error(probe(copy, "5"), "collect.json is missing");
  // A DAgger rollout (an episode driven by a policy, its "driver" attribute) is not the
  // expert's to replay.
  const std::filesystem::path rollout = run.dir() / "rollout-copy";
  std::filesystem::copy(run.data(), rollout);
  const std::string mark = run.dir() / "mark.py";
  test::write_text(mark, "import sys, h5py\n"
                         "for p in sys.argv[1:]:\n"
                         "    with h5py.File(p, 'r+') as f:\n"
                         "        f.attrs['driver'] = 'bc-oh beta 0.5'\n");
  std::vector<std::string> mark_args{CD_PYTHON, mark};
  for (const auto& entry : std::filesystem::directory_iterator(rollout))
    if (entry.path().extension() == ".h5") mark_args.push_back(entry.path());
  const test::CommandResult marked = test::run_command(mark_args);
  ASSERT_TRUE(marked.exited && marked.exit_code == 0) << marked.describe();
  test::expect_one_line_error(probe(rollout, "5"), "was driven by bc-oh beta 0.5 (a DAgger rollout)");
  test::run_cli_ok(test::eval_args(run.config(), "bc-oh", run.run(), run.suite(),
                                   run.dir() / "rec", 1, {"--record"}));
  test::run_cli_ok({"report", run.dir() / "rec", "--html", run.dir() / "page.html", "--episodes", "0"});
  EXPECT_NE(test::read_text(run.dir() / "page.html").find("data:image/png;base64,"),
            std::string::npos);

  // The BEV's world refuses the camera's checkpoint, naming both views.
  const std::string bev = test::write_test_config(run.dir(), "empty", kTrain, "bev.toml");
  const test::CommandResult r =
      run.refused_eval(bev, "bev", "was trained on camera frames (3x32x96)");
  EXPECT_NE(r.err.find("renders bev frames"), std::string::npos) << r.err;

  // The BEV's perception noise is not the camera's condition.
  run.refused_eval(run.config(), "shifted", "held-out weather", {"--sensor", "shifted"});
}

TEST(CameraView, ABevCheckpointIsRefusedByTheCamera) {
  CD_NEEDS_SUMO();
  test::TinyRun run({.method = "bc-so",
                     .traffic = "empty",
                     .extra = kTrain,
                     .suite = {.traffic = "empty", .scenarios = {"route"}}});
  const std::string camera =
      test::write_test_config(run.dir(), "empty", kTrain + kCamera, "camera.toml");
  const test::CommandResult r = run.refused_eval(camera, "camera", "was trained on bev frames");
  EXPECT_NE(r.err.find("renders camera frames (3x32x96"), std::string::npos) << r.err;
}

// town --moment-preview: the BEV (2x) beside the camera in each weather, one PNG whose size
// follows from the settings; an unknown weather is one line.
TEST(CameraView, MomentPreviewDrawsTheBevBesideEachWeather) {
  CD_NEEDS_SUMO();
  test::TempDir dir("cdtest-moment");
  const std::string config = test::write_test_config(dir, "regular", kCamera, "moment.toml");
  const std::string png = dir / "moment.png";
  test::run_cli_ok({"town", "town-a", "--config", config, "--moment-preview", png, "--steps", "5",
                    "--weathers", "clear-noon", "wet-noon", "after-rain-dusk"});
  const std::string bytes = test::read_text(png);
  ASSERT_GT(bytes.size(), 24u);
  auto be32 = [&](size_t at) {
    return (uint32_t(uint8_t(bytes[at])) << 24) | (uint32_t(uint8_t(bytes[at + 1])) << 16) |
           (uint32_t(uint8_t(bytes[at + 2])) << 8) | uint32_t(uint8_t(bytes[at + 3]));
  };
  EXPECT_EQ(bytes.substr(1, 3), "PNG");
  EXPECT_EQ(be32(16), 2u * 64 + 4 + 96) << "width: the BEV at 2x, a gap, the camera";
  EXPECT_EQ(be32(20), 2u * 64) << "height: the taller of the BEV (128) and 3 x 32 + 2 gaps";
  const test::CommandResult r =
      test::run_cli({"town", "town-a", "--config", config, "--moment-preview", dir / "bad.png",
                     "--weathers", "moonlight"});
  test::expect_one_line_error(r, "moonlight");
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.png"));
}

}  // namespace
}  // namespace cd
