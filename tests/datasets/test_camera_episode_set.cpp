// Driving folders of the front camera (sense.view = "camera") as training data
// (datasets/episode_set): the RGB bytes kept as recorded behind planes01 (byte / 255, the
// network's input) and planes255, the channel names red, green, blue; the frames held in memory
// as the file stores them (one deflate stream per frame), a damaged one a DataError naming its
// file and frame, a file stored otherwise (contiguous, by h5py) read decoded; a folder mixing
// camera and BEV episodes is refused, naming both files.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "../support/test_support.hpp"
#include "core/error.hpp"
#include "data/h5_episode.hpp"
#include "datasets/episode_set.hpp"

namespace cd {
namespace {

// A hand-made driving episode of T frames: camera RGB (value (t + 3c + 5p) % 256 at pixel p of
// channel c) or BEV planes (0/255), with the names the recorders give them.
void write_driving_episode(const std::string& path, bool camera, int T = 3, int H = 4, int W = 6) {
  EpisodeData d;
  d.channels = camera ? 3 : 2;
  d.height = H;
  d.width = W;
  d.action_dim = 2;
  FrameBytes& frames = camera ? d.rgb : d.bev;
  const int P = H * W;
  for (int t = 0; t < T; ++t) {
    for (int c = 0; c < d.channels; ++c)
      for (int p = 0; p < P; ++p)
        frames.push_back(camera ? static_cast<uint8_t>((t + 3 * c + 5 * p) % 256)
                                : static_cast<uint8_t>((t + c + p) % 2 ? 255 : 0));
    d.speed.push_back(1.0f);
    d.action.insert(d.action.end(), {0.5f, 0.0f});
    d.command.push_back(0);
    d.pose.insert(d.pose.end(), {float(t), 0.0f, 0.0f});
    d.noise.push_back(0);
  }
  EpisodeMeta m;
  m.town = "town-a";
  m.dt = 0.1;
  m.metres_per_pixel = camera ? 0.0 : 0.5;
  m.channels = camera ? std::vector<std::string>{"red", "green", "blue"}
                      : std::vector<std::string>{"road", "vehicles"};
  m.action_names = {"throttle", "brake"};
  write_episode(path, m, d);
}

TEST(CameraEpisodeSet, LoadsRgbBytesAsRecorded) {
  test::TempDir dir("cdtest-camset");
  write_driving_episode(dir / "episode_000000.h5", true);
  write_driving_episode(dir / "episode_000001.h5", true, 5);
  const EpisodeSet set = load_episode_set(dir.path());
  EXPECT_EQ(set.domain, "driving");
  EXPECT_EQ(set.layout, FrameLayout::Bytes);
  EXPECT_EQ(set.channels, 3);
  EXPECT_EQ(set.height, 4);
  EXPECT_EQ(set.width, 6);
  EXPECT_EQ(set.channel_names, (std::vector<std::string>{"red", "green", "blue"}));
  ASSERT_EQ(set.episodes.size(), 2u);
  EXPECT_EQ(set.episodes[1].frames, 5);
  // Held as stored: T + 1 offsets over the streams (these tiny noisy frames do not shrink;
  // docs/camera.md measures real ones).
  ASSERT_EQ(set.episodes[1].frame_offsets.size(), 6u);
  EXPECT_EQ(set.episodes[1].frame_data.size(), set.episodes[1].frame_offsets.back());
  EXPECT_EQ(set.frame_memory(), set.episodes[0].frame_data.size() + set.episodes[1].frame_data.size() +
                                    (4 + 6) * sizeof(uint64_t));
  const size_t fv = set.frame_values();
  ASSERT_EQ(fv, 3u * 4 * 6);
  std::vector<float> unit(fv);
  std::vector<uint8_t> bytes(fv);
  set.planes01(1, 4, unit.data());
  set.planes255(1, 4, bytes.data());
  for (int c = 0; c < 3; ++c)
    for (int p = 0; p < 24; ++p) {
      const size_t i = static_cast<size_t>(c) * 24 + p;
      const int want = (4 + 3 * c + 5 * p) % 256;
      EXPECT_EQ(bytes[i], want) << "c " << c << " p " << p;
      EXPECT_FLOAT_EQ(unit[i], static_cast<float>(want) / 255.0f) << "c " << c << " p " << p;
    }
}

TEST(CameraEpisodeSet, ADamagedStoredFrameIsADataErrorAndOtherStoragesAreDecoded) {
  test::TempDir dir("cdtest-camset-stored");
  write_driving_episode(dir / "episode_000000.h5", true);
  EpisodeSet set = load_episode_set(dir.path());
  PackedEpisode& ep = set.episodes[0];
  ASSERT_EQ(ep.frame_offsets.size(), 4u);
  std::vector<uint8_t> out(set.frame_values());
  ep.frame_data[ep.frame_offsets[1] + 2] ^= 0x5a;  // inside frame 1's stream
  try {
    set.planes255(0, 1, out.data());
    FAIL() << "a damaged frame was inflated";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("episode_000000.h5 frame 1"), std::string::npos) << e.what();
  }
  // The same frames stored contiguously (h5py, no chunks): read decoded, the same values.
  const test::CommandResult r = test::run_python(R"PY(
import sys
import h5py
with h5py.File(sys.argv[1], "a") as f:
    x = f["frames"][...]
    del f["frames"]
    f.create_dataset("frames", data=x)
)PY", {dir / "episode_000000.h5"}, dir);
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  const EpisodeSet plain = load_episode_set(dir.path());
  EXPECT_TRUE(plain.episodes[0].frame_offsets.empty());
  EXPECT_EQ(plain.episodes[0].frame_data.size(), 3u * 3 * 4 * 6);
  plain.planes255(0, 2, out.data());
  for (int c = 0; c < 3; ++c)
    for (int p = 0; p < 24; ++p) EXPECT_EQ(out[size_t(c) * 24 + p], (2 + 3 * c + 5 * p) % 256);
}

TEST(CameraEpisodeSet, AFolderMixingViewsIsRefused) {
  test::TempDir dir("cdtest-camset-mixed");
  write_driving_episode(dir / "episode_000000.h5", true);
  write_driving_episode(dir / "episode_000001.h5", false);
  try {
    load_episode_set(dir.path());
    FAIL() << "expected DataError";
  } catch (const DataError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("episode_000001.h5"), std::string::npos) << msg;
    EXPECT_NE(msg.find("holds BEV frames but episode_000000.h5 holds camera frames"),
              std::string::npos)
        << msg;
  }
}

}  // namespace
}  // namespace cd
