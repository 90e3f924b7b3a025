#include "data/h5_episode.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "core/error.hpp"

#ifndef CD_PYTHON
#define CD_PYTHON "/usr/bin/python3"
#endif

namespace cd {
namespace {

namespace fs = std::filesystem;

// A fresh directory per test, removed afterwards.
class H5EpisodeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    static std::atomic<int> counter{0};
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("cd_h5_" + std::to_string(::getpid()) + "_" +
                                        std::to_string(counter++) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

// BEV pattern the Python oracle recomputes.
uint8_t bev_value(size_t t, size_t c, size_t h, size_t w) {
  return static_cast<uint8_t>((t * 7 + c * 13 + h * 3 + w) % 251);
}

EpisodeData make_data(int frames = 5, int channels = 3, int height = 4, int width = 6) {
  EpisodeData d;
  d.channels = channels;
  d.height = height;
  d.width = width;
  d.action_dim = 2;
  for (int t = 0; t < frames; ++t) {
    for (int c = 0; c < channels; ++c)
      for (int h = 0; h < height; ++h)
        for (int w = 0; w < width; ++w) d.bev.push_back(bev_value(t, c, h, w));
    d.speed.push_back(0.5f * static_cast<float>(t));
    d.action.push_back(static_cast<float>(t));
    d.action.push_back(static_cast<float>(t) + 0.25f);
    d.command.push_back(t % 4 - 1);
    d.pose.push_back(static_cast<float>(t));
    d.pose.push_back(-static_cast<float>(t));
    d.pose.push_back(0.01f * static_cast<float>(t));
    d.causes["lead_distance"].push_back(100.0f - static_cast<float>(t));
    d.causes["light_red"].push_back(static_cast<float>(t % 2));
    d.noise.push_back(t == 2 || t == 3 ? 1 : 0);
  }
  return d;
}

EpisodeMeta make_meta(int channels = 3) {
  EpisodeMeta m;
  m.town = "Town01";
  m.suite = "train";
  m.seed = 12345678901234ULL;  // above 2^32: checks the 64-bit attribute
  m.dt = 0.1;
  for (int c = 0; c < channels; ++c) m.channels.push_back("ch" + std::to_string(c));
  m.metres_per_pixel = 0.5;
  m.action_names = {"throttle", "brake"};
  m.outcome = "success";
  m.extra = {{"route", "r3"}, {"noise", "0.2"}, {"empty", ""}};
  return m;
}

void expect_same_meta(const EpisodeMeta& a, const EpisodeMeta& b) {
  EXPECT_EQ(a.format_version, b.format_version);
  EXPECT_EQ(a.town, b.town);
  EXPECT_EQ(a.suite, b.suite);
  EXPECT_EQ(a.seed, b.seed);
  EXPECT_EQ(a.dt, b.dt);
  EXPECT_EQ(a.channels, b.channels);
  EXPECT_EQ(a.metres_per_pixel, b.metres_per_pixel);
  EXPECT_EQ(a.action_names, b.action_names);
  EXPECT_EQ(a.outcome, b.outcome);
  EXPECT_EQ(a.extra, b.extra);
}

std::string read_bytes(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Runs a Python script on `file`, returning its exit code.
int run_python(const fs::path& dir, const std::string& script, const std::string& file) {
  const fs::path script_path = dir / "oracle.py";
  std::ofstream(script_path) << script;
  const std::string cmd = std::string(CD_PYTHON) + " '" + script_path.string() + "' '" + file + "'";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST_F(H5EpisodeTest, RoundTripKeepsDataAndMeta) {
  const EpisodeData data = make_data();
  const EpisodeMeta meta = make_meta();
  write_episode(path("ep.h5"), meta, data);

  EpisodeMeta got_meta;
  const EpisodeData got = read_episode(path("ep.h5"), &got_meta);
  EXPECT_EQ(got.channels, data.channels);
  EXPECT_EQ(got.height, data.height);
  EXPECT_EQ(got.width, data.width);
  EXPECT_EQ(got.action_dim, data.action_dim);
  EXPECT_EQ(got.bev, data.bev);
  EXPECT_EQ(got.speed, data.speed);
  EXPECT_EQ(got.action, data.action);
  EXPECT_EQ(got.command, data.command);
  EXPECT_EQ(got.pose, data.pose);
  EXPECT_EQ(got.noise, data.noise);
  EXPECT_EQ(got.causes, data.causes);
  expect_same_meta(got_meta, meta);
  expect_same_meta(read_episode_meta(path("ep.h5")), meta);
}

TEST_F(H5EpisodeTest, SingleFrameWithoutCausesRoundTrips) {
  EpisodeData data = make_data(1, 1, 1, 1);
  data.causes.clear();
  const EpisodeMeta meta = make_meta(1);
  write_episode(path("one.h5"), meta, data);
  const EpisodeData got = read_episode(path("one.h5"));
  EXPECT_EQ(got.frames(), 1u);
  EXPECT_EQ(got.bev, data.bev);
  EXPECT_TRUE(got.causes.empty());
}

TEST_F(H5EpisodeTest, OverwritesAnExistingFile) {
  write_episode(path("ep.h5"), make_meta(), make_data(5));
  write_episode(path("ep.h5"), make_meta(), make_data(8));
  EXPECT_EQ(read_episode(path("ep.h5")).frames(), 8u);
}

TEST_F(H5EpisodeTest, H5pyReadsTheLayout) {
  const int T = 6, C = 3, H = 4, W = 5;
  write_episode(path("ep.h5"), make_meta(C), make_data(T, C, H, W));
  const std::string script = R"PY(
import sys
import h5py
import numpy as np

def text(v):
    return v.decode() if isinstance(v, bytes) else str(v)

def check(cond, what):
    if not cond:
        print("h5py oracle mismatch:", what, file=sys.stderr)
        sys.exit(1)

T, C, H, W, A = 6, 3, 4, 5, 2
with h5py.File(sys.argv[1], "r") as f:
    check(sorted(f.keys()) == ["action", "bev", "causes", "command", "noise", "pose", "speed"],
          "names %s" % sorted(f.keys()))
    check(f["noise"].dtype == np.uint8 and f["noise"].shape == (T,), "noise layout")
    check(list(f["noise"][...]) == [1 if t in (2, 3) else 0 for t in range(T)], "noise values")
    want = {"bev": (np.uint8, (T, C, H, W)), "speed": (np.float32, (T,)),
            "action": (np.float32, (T, A)), "command": (np.int32, (T,)),
            "pose": (np.float32, (T, 3))}
    for name, (dtype, shape) in want.items():
        check(f[name].dtype == dtype, "%s dtype %s" % (name, f[name].dtype))
        check(f[name].shape == shape, "%s shape %s" % (name, f[name].shape))
    check(f["bev"].chunks == (1, C, H, W), "bev chunks %s" % (f["bev"].chunks,))
    check(f["bev"].compression == "gzip", "bev compression")
    t, c, h, w = np.indices((T, C, H, W))
    check(np.array_equal(f["bev"][...], ((t * 7 + c * 13 + h * 3 + w) % 251).astype(np.uint8)),
          "bev values")
    check(np.array_equal(f["speed"][...], 0.5 * np.arange(T, dtype=np.float32)), "speed")
    check(np.array_equal(f["action"][:, 1], np.arange(T, dtype=np.float32) + 0.25), "action")
    check(list(f["command"][...]) == [i % 4 - 1 for i in range(T)], "command")
    check(np.allclose(f["pose"][:, 2], 0.01 * np.arange(T)), "pose")
    check(sorted(f["causes"].keys()) == ["lead_distance", "light_red"], "cause names")
    for name in f["causes"]:
        check(f["causes"][name].dtype == np.float32 and f["causes"][name].shape == (T,),
              "causes/%s layout" % name)
    check(np.array_equal(f["causes/lead_distance"][...], 100.0 - np.arange(T)), "lead_distance")
    check(np.array_equal(f["causes/light_red"][...], np.arange(T) % 2), "light_red")
    a = f.attrs
    check(int(a["format_version"]) == 1, "format_version")
    check(text(a["town"]) == "Town01", "town %r" % a["town"])
    check(text(a["suite"]) == "train" and text(a["outcome"]) == "success", "suite/outcome")
    check(int(a["seed"]) == 12345678901234 and a["seed"].dtype == np.uint64, "seed")
    check(float(a["dt"]) == 0.1 and float(a["metres_per_pixel"]) == 0.5, "dt/mpp")
    check(int(a["frames"]) == T, "frames")
    check([text(x) for x in a["channels"]] == ["ch0", "ch1", "ch2"], "channels")
    check([text(x) for x in a["action_names"]] == ["throttle", "brake"], "action_names")
    check(text(a["route"]) == "r3" and text(a["empty"]) == "", "extra attributes")
)PY";
  EXPECT_EQ(run_python(dir_, script, path("ep.h5")), 0);
}

TEST_F(H5EpisodeTest, ReadsVariableLengthStringsAndReportsMissingDatasets) {
  write_episode(path("ep.h5"), make_meta(), make_data());
  // h5py writes str attributes as variable-length strings.
  const std::string edit = R"PY(
import sys
import h5py
with h5py.File(sys.argv[1], "r+") as f:
    f.attrs["town"] = "Town02"
    f.attrs["channels"] = ["a", "bb", "ccc"]
)PY";
  ASSERT_EQ(run_python(dir_, edit, path("ep.h5")), 0);
  const EpisodeMeta meta = read_episode_meta(path("ep.h5"));
  EXPECT_EQ(meta.town, "Town02");
  EXPECT_EQ(meta.channels, (std::vector<std::string>{"a", "bb", "ccc"}));
  EXPECT_EQ(read_episode(path("ep.h5")).frames(), 5u);

  const std::string drop = R"PY(
import sys
import h5py
with h5py.File(sys.argv[1], "r+") as f:
    del f["pose"]
)PY";
  // A file written before the noise mask existed reads as noise-free.
  const std::string no_mask = R"PY(
import sys
import h5py
with h5py.File(sys.argv[1], "r+") as f:
    del f["noise"]
)PY";
  ASSERT_EQ(run_python(dir_, no_mask, path("ep.h5")), 0);
  EXPECT_EQ(read_episode(path("ep.h5")).noise, std::vector<uint8_t>(5, 0));
  // An episode recorded without a mask is written with an all-zero one.
  EpisodeData unmasked = make_data();
  unmasked.noise.clear();
  write_episode(path("unmasked.h5"), make_meta(), unmasked);
  EXPECT_EQ(read_episode(path("unmasked.h5")).noise, std::vector<uint8_t>(5, 0));

  ASSERT_EQ(run_python(dir_, drop, path("ep.h5")), 0);
  try {
    read_episode(path("ep.h5"));
    FAIL() << "expected DataError";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("'pose'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(path("ep.h5")), std::string::npos) << e.what();
  }
}

TEST_F(H5EpisodeTest, IdenticalInputGivesIdenticalBytes) {
  const EpisodeData data = make_data(20, 8, 16, 16);
  const EpisodeMeta meta = make_meta(8);
  write_episode(path("a.h5"), meta, data);
  // Past a second boundary, so a stored timestamp would show up.
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  write_episode(path("b.h5"), meta, data);
  const std::string a = read_bytes(path("a.h5"));
  ASSERT_FALSE(a.empty());
  EXPECT_TRUE(a == read_bytes(path("b.h5")));
}

TEST_F(H5EpisodeTest, LeavesNoTemporaryFiles) {
  write_episode(path("ep.h5"), make_meta(), make_data());
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir_)) {
    names.push_back(entry.path().filename().string());
  }
  EXPECT_EQ(names, std::vector<std::string>{"ep.h5"});
}

TEST_F(H5EpisodeTest, WriteIntoMissingDirectoryThrowsIoError) {
  const std::string target = path("missing/ep.h5");
  EXPECT_THROW(write_episode(target, make_meta(), make_data()), IoError);
  EXPECT_FALSE(fs::exists(target));
}

TEST_F(H5EpisodeTest, FailedCommitRemovesTemporaryFile) {
  // A non-empty directory in the way makes the final rename fail after the file is written.
  fs::create_directories(dir_ / "ep.h5");
  std::ofstream(dir_ / "ep.h5" / "keep") << "x";
  EXPECT_THROW(write_episode(path("ep.h5"), make_meta(), make_data()), IoError);
  for (const auto& entry : fs::directory_iterator(dir_)) {
    EXPECT_NE(entry.path().extension(), ".tmp") << entry.path();
  }
}

TEST_F(H5EpisodeTest, MissingFileThrowsIoError) {
  EXPECT_THROW(read_episode(path("nope.h5")), IoError);
  EXPECT_THROW(read_episode_meta(path("nope.h5")), IoError);
}

TEST_F(H5EpisodeTest, TruncatedFileThrowsDataErrorQuietly) {
  write_episode(path("ep.h5"), make_meta(), make_data(50, 3, 16, 16));
  fs::resize_file(path("ep.h5"), fs::file_size(path("ep.h5")) / 2);
  ::testing::internal::CaptureStderr();
  EXPECT_THROW(read_episode(path("ep.h5")), DataError);
  EXPECT_THROW(read_episode_meta(path("ep.h5")), DataError);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
}

TEST_F(H5EpisodeTest, CorruptMetadataThrowsDataErrorWithNothingOnStderr) {
  write_episode(path("ep.h5"), make_meta(), make_data());
  {
    // Byte 100 lies in the root group's object header, just after the 48-byte superblock.
    std::fstream f(path("ep.h5"), std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(100);
    const char c = static_cast<char>(f.get());
    f.seekp(100);
    f.put(static_cast<char>(c ^ 0x5a));
  }
  // In a child process, so that HDF5's exit handlers run too: they must print nothing.
  EXPECT_EXIT(
      {
        try {
          read_episode(path("ep.h5"));
        } catch (const DataError&) {
          std::exit(0);
        }
        std::exit(1);
      },
      ::testing::ExitedWithCode(0), "^$");
}

TEST_F(H5EpisodeTest, TextFileThrowsDataError) {
  std::ofstream(path("text.h5")) << "this is not an HDF5 file\n";
  EXPECT_THROW(read_episode(path("text.h5")), DataError);
  EXPECT_THROW(read_episode_meta(path("text.h5")), DataError);
}

TEST_F(H5EpisodeTest, InconsistentDataThrowsDataErrorOnWrite) {
  EpisodeData data = make_data();
  data.speed.push_back(1.0f);  // one frame more than bev
  EXPECT_THROW(write_episode(path("ep.h5"), make_meta(), data), DataError);

  data = make_data();
  data.causes["light_red"].pop_back();
  try {
    write_episode(path("ep.h5"), make_meta(), data);
    FAIL() << "expected DataError";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("causes/light_red"), std::string::npos) << e.what();
  }

  data = make_data();
  data.pose.pop_back();
  EXPECT_THROW(write_episode(path("ep.h5"), make_meta(), data), DataError);

  EpisodeMeta meta = make_meta();
  meta.channels.pop_back();  // names must match the BEV channels
  EXPECT_THROW(write_episode(path("ep.h5"), meta, make_data()), DataError);

  meta = make_meta();
  meta.extra["town"] = "clash";  // would overwrite a standard attribute
  EXPECT_THROW(write_episode(path("ep.h5"), meta, make_data()), DataError);

  EXPECT_FALSE(fs::exists(path("ep.h5")));
}

// The front camera's frames (sense.view = "camera", SPEC section 16): the dataset "frames" in
// place of "bev", (T, 3, H, W) uint8, one frame per chunk, deflated; read back as rgb. A file
// holding both, or a camera episode of other than 3 channels, is refused on write.
TEST_F(H5EpisodeTest, CameraFramesAreTheFramesDataset) {
  const int T = 4, C = 3, H = 5, W = 7;
  EpisodeData data = make_data(T, C, H, W);
  data.rgb.assign(data.bev.begin(), data.bev.end());
  data.bev.clear();
  EXPECT_TRUE(data.camera());
  write_episode(path("cam.h5"), make_meta(C), data);
  const EpisodeData got = read_episode(path("cam.h5"));
  EXPECT_TRUE(got.camera());
  EXPECT_TRUE(got.bev.empty() && got.bev_packed.empty());
  EXPECT_EQ(got.rgb, data.rgb);
  EXPECT_EQ(got.channels, C);
  EXPECT_EQ(got.height, H);
  EXPECT_EQ(got.width, W);
  std::vector<uint8_t> planes(got.frame_bytes());
  got.frame_planes(2, planes.data());
  EXPECT_EQ(planes[0], bev_value(2, 0, 0, 0));
  EXPECT_EQ(planes.back(), bev_value(2, C - 1, H - 1, W - 1));

  const std::string script = R"PY(
import sys
import h5py
import numpy as np
T, C, H, W = 4, 3, 5, 7
with h5py.File(sys.argv[1], "r") as f:
    assert sorted(f.keys()) == ["action", "causes", "command", "frames", "noise", "pose", "speed"], sorted(f.keys())
    x = f["frames"]
    assert x.dtype == np.uint8 and x.shape == (T, C, H, W), (x.dtype, x.shape)
    assert x.chunks == (1, C, H, W) and x.compression == "gzip", (x.chunks, x.compression)
    t, c, h, w = np.indices((T, C, H, W))
    assert np.array_equal(x[...], ((t * 7 + c * 13 + h * 3 + w) % 251).astype(np.uint8))
)PY";
  EXPECT_EQ(run_python(dir_, script, path("cam.h5")), 0);

  EpisodeData both = data;
  both.bev = both.rgb;
  EXPECT_THROW(write_episode(path("both.h5"), make_meta(C), both), DataError);
  EpisodeData grey = make_data(T, 1, H, W);
  grey.rgb.assign(grey.bev.begin(), grey.bev.end());
  grey.bev.clear();
  EXPECT_THROW(write_episode(path("grey.h5"), make_meta(1), grey), DataError);
  EXPECT_FALSE(fs::exists(path("both.h5")) || fs::exists(path("grey.h5")));
}

}  // namespace
}  // namespace cd
