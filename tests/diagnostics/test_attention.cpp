// Attention maps (diagnostics/attention): Grad-CAM on a hand-made feature map, the bilinear
// resampling against torch's, the runner's feature-map gradient and the whole map against an
// independent autograd computation on a tiny trained policy, and the command itself (PNG grids
// that decode to three panels, attention.json shares, frame selection, same bytes twice).
#include "diagnostics/attention.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numeric>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <torch/torch.h>

#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#define STBI_ONLY_PNG
#include <stb/stb_image.h>

#include "../support/fake_episodes.hpp"
#include "../support/tiny_training.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "datasets/episode_set.hpp"
#include "inference/policy_runner.hpp"
#include "methods/method.hpp"
#include "nn/policy_nets.hpp"
#include "runs/checkpoint.hpp"
#include "sense/bev_colour.hpp"

namespace cd {
namespace {

using nlohmann::json;
using test::TempDir;

struct TorchThreads {
  TorchThreads() { torch::set_num_threads(1); }
} const kOneThread;

// ---- Grad-CAM by hand ---------------------------------------------------------------------

TEST(GradCam, HandMadeMapIsConcentratedWhereTheWeightedChannelIsOn) {
  // Channel 0 is on at the top-left cell only and raises the output (mean gradient 2);
  // channel 1 is on everywhere and lowers it (mean gradient -0.5).
  FeatureMapGradient g;
  g.channels = 2;
  g.height = g.width = 2;
  g.activation = {1, 0, 0, 0, /**/ 1, 1, 1, 1};
  g.gradient = {2, 2, 2, 2, /**/ -1, 0, -1, 0};
  // cam = 2 * [1,0,0,0] - 0.5 * [1,1,1,1] = [1.5, -0.5, -0.5, -0.5] -> ReLU [1.5, 0, 0, 0].
  double raw_max = -1;
  std::vector<float> map = grad_cam(g, 4, 4, &raw_max);
  EXPECT_DOUBLE_EQ(raw_max, 1.5);
  // Bilinear 2 -> 4 (align_corners = false): output pixel i samples source 0.5 i - 0.25
  // (clamped at 0), so the top-left cell's weight along each axis is 1, 0.75, 0.25, 0.
  const float w[4] = {1.0f, 0.75f, 0.25f, 0.0f};
  ASSERT_EQ(map.size(), 16u);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 4; ++x) EXPECT_NEAR(map[y * 4 + x], w[y] * w[x], 1e-6) << y << "," << x;

  // Everything the output depends on lowers it: ReLU leaves nothing, and zero stays zero.
  g.gradient = {-1, -1, -1, -1, /**/ -1, -1, -1, -1};
  map = grad_cam(g, 4, 4, &raw_max);
  EXPECT_EQ(raw_max, 0.0);
  EXPECT_EQ(map, std::vector<float>(16, 0.0f));

  g.gradient.pop_back();
  EXPECT_THROW(grad_cam(g, 4, 4), Error);
}

TEST(GradCam, BilinearResamplingMatchesTorch) {
  torch::manual_seed(3);
  const std::array<std::array<int, 4>, 4> cases = {
      {{3, 5, 16, 20}, {2, 2, 32, 32}, {4, 4, 64, 64}, {1, 3, 8, 9}}};
  for (const auto& [h, w, H, W] : cases) {
    torch::Tensor small = torch::rand({1, 1, h, w});
    torch::Tensor big = torch::upsample_bilinear2d(small, {H, W}, /*align_corners=*/false);
    std::vector<float> in(small.data_ptr<float>(), small.data_ptr<float>() + h * w);
    std::vector<float> out = resize_bilinear(in, h, w, H, W);
    const float* ref = big.contiguous().data_ptr<float>();
    for (int i = 0; i < H * W; ++i) ASSERT_NEAR(out[i], ref[i], 1e-6) << h << "x" << w << " " << i;
  }
}

TEST(GradCam, TopChannelIsTheOneDrawnOnTop) {
  // 3 channels, 1 x 3 pixels: nothing; channel 0; channels 0 and 2.
  const unsigned char frame[9] = {0, 255, 255, /**/ 0, 0, 0, /**/ 0, 0, 255};
  EXPECT_EQ(top_channel(frame, 3, 1, 3), (std::vector<int>{3, 0, 2}));
}

// ---- a tiny trained policy ----------------------------------------------------------------

// 3 episodes of 32 x 32 frames (the small backbone's map is then 2 x 2), 8 channels.
constexpr int kSize = 32;

std::string train(const TempDir& dir, const std::string& method, const std::string& name) {
  return test::train_tiny_run(dir, method, name);
}

// The observation of episode e at step t through the checkpoint's history.
struct Observation3 {
  std::vector<std::vector<uint8_t>> buffers;
  std::vector<const uint8_t*> frames;
  Observation3(const EpisodeSet& set, int e, int t, int K, int stride) {
    for (int k = 0; k < K; ++k) {
      buffers.emplace_back(set.frame_values());
      set.planes255(e, t - (K - 1 - k) * stride, buffers.back().data());
    }
    for (auto& b : buffers) frames.push_back(b.data());
  }
};

TEST(GradCam, RunnerGradientMatchesAnIndependentAutogradComputation) {
  TempDir dir("cd-gradcam");
  test::write_fake_folder(dir / "data", 3, {.frames = 24, .height = kSize, .width = kSize});
  const std::string run = train(dir, "bc-oh", "oh");
  EpisodeSet set = load_episode_set(dir / "data");
  PolicyRunner runner(run);
  const int e = 1, t = 13;
  Observation3 obs(set, e, t, 3, 2);
  const double speed = set.episodes[e].speed[t];
  const int command = set.episodes[e].command[t];

  FeatureMapGradient g;
  const PolicyStep with_grad = runner.run_with_gradient(obs.frames.data(), speed, command, nullptr, g);
  const std::vector<float> action = runner.last_action();
  const PolicyStep plain = runner.run(obs.frames.data(), speed, command);
  EXPECT_EQ(g.module, "policy");
  EXPECT_EQ(action, runner.last_action()) << "the gradient pass must not change the action";
  EXPECT_EQ(with_grad.throttle, plain.throttle);
  EXPECT_EQ(with_grad.brake, plain.brake);
  ASSERT_EQ(g.channels, 32);  // the 1x1 squeeze
  ASSERT_EQ(g.height, 2);
  ASSERT_EQ(g.width, 2);

  // Independently: the networks from the run folder, the map made a leaf, the rest of the
  // forward pass written out, backward() into the leaf's .grad.
  const Checkpoint ck = require_checkpoint(run);
  const InputFormat& in = ck.input;
  PolicyNets nets(policy_layout(ck.method, ck.model, ck.residual, ck.fca, in.channels, in.height,
                                in.width, in.action_dim));
  nets.load_bytes(read_file_bytes(run + "/" + kBestFile), torch::kCPU, "best.pt");
  nets.set_training(false);
  torch::Tensor image = torch::zeros({1, 3 * in.channels, in.height, in.width});
  const size_t fv = set.frame_values();
  for (int k = 0; k < 3; ++k)
    for (size_t i = 0; i < fv; ++i)
      image.data_ptr<float>()[k * fv + i] = obs.frames[k][i] ? 1.0f : 0.0f;
  PolicyNet& net = nets.policy;
  torch::Tensor A = net->small->feature_map(image).detach().requires_grad_(true);
  torch::Tensor f = net->small->features_of(A);
  torch::Tensor j = net->fusion->forward(torch::cat({f, net->measurement->forward(torch::zeros({1, 1}))}, 1));
  torch::Tensor a = net->act(j, torch::full({1}, command, torch::kInt64));
  // The default signed pedals: one output, throttle - brake, decoded by the runner into
  // throttle = max(v, 0) and brake = max(-v, 0); Grad-CAM explains v.
  ASSERT_EQ(ck.model.pedals, "signed");
  ASSERT_EQ(a.size(1), 1);
  EXPECT_NEAR(a[0][0].item<float>(), action[0] - action[1], 1e-6);
  a[0][0].backward();
  torch::Tensor grad = A.grad().contiguous();
  torch::Tensor act = A.detach().contiguous();
  for (int i = 0; i < 32 * 4; ++i) {
    ASSERT_NEAR(g.activation[i], act.data_ptr<float>()[i], 1e-6) << i;
    ASSERT_NEAR(g.gradient[i], grad.data_ptr<float>()[i], 1e-6) << i;
  }
  EXPECT_GT(grad.abs().sum().item<float>(), 0.0f);

  // Grad-CAM in torch: channel weights, ReLU of the weighted sum, torch's bilinear upsampling.
  torch::Tensor weights = grad.mean({2, 3}, /*keepdim=*/true);
  torch::Tensor cam = torch::relu((weights * act).sum(1, /*keepdim=*/true));
  torch::Tensor big = torch::upsample_bilinear2d(cam, {kSize, kSize}, false);
  const float peak = big.max().item<float>();
  if (peak > 0) big = big / peak;
  const std::vector<float> map = grad_cam(g, kSize, kSize);
  const float* ref = big.contiguous().data_ptr<float>();
  for (int i = 0; i < kSize * kSize; ++i) ASSERT_NEAR(map[i], ref[i], 1e-5) << i;
}

TEST(GradCam, ResidualTakesThePolicyModulesOwnBackbone) {
  TempDir dir("cd-gradcam-res");
  test::write_fake_folder(dir / "data", 3, {.frames = 24, .height = kSize, .width = kSize});
  const std::string run = train(dir, "residual", "res");
  EpisodeSet set = load_episode_set(dir / "data");
  PolicyRunner runner(run);
  Observation3 obs(set, 0, 9, 3, 2);
  FeatureMapGradient g;
  runner.run_with_gradient(obs.frames.data(), 0, 0, nullptr, g);
  const std::vector<float> action = runner.last_action();
  runner.run(obs.frames.data(), 0, 0);
  EXPECT_EQ(action, runner.last_action());
  EXPECT_EQ(g.module, "policy");
  EXPECT_EQ(g.channels * g.height * g.width, 32 * 2 * 2);
  EXPECT_EQ(g.gradient.size(), g.activation.size());
}

// ---- the command --------------------------------------------------------------------------

std::pair<int, int> decoded_size(const std::string& path, std::vector<unsigned char>* pixels) {
  const std::string bytes = test::read_text(path);
  int w = 0, h = 0, n = 0;
  unsigned char* data = stbi_load_from_memory(reinterpret_cast<const unsigned char*>(bytes.data()),
                                              static_cast<int>(bytes.size()), &w, &h, &n, 3);
  if (!data) return {0, 0};
  if (pixels) pixels->assign(data, data + static_cast<size_t>(w) * h * 3);
  stbi_image_free(data);
  return {w, h};
}

TEST(Attention, WritesReadableGridsAndSharesOfTheMapMass) {
  TempDir dir("cd-attention");
  test::write_fake_folder(dir / "data", 3, {.frames = 24, .height = kSize, .width = kSize});
  const std::string run = train(dir, "bc-oh", "oh");
  AttentionOptions o;
  o.checkpoint = run;
  o.data = dir / "data";
  o.out = dir / "maps";
  o.frames = 3;
  o.select = "all";
  AttentionReport r = run_attention(o);
  EXPECT_EQ(r.candidates, 3 * (24 - 4));  // history 3, stride 2: t >= 4
  ASSERT_EQ(r.frames.size(), 3u);
  EXPECT_EQ(test::list_dir(o.out), (std::vector<std::string>{"attention.json", "attention_000.png",
                                                             "attention_001.png",
                                                             "attention_002.png"}));
  // Three 32 x 32 panels at scale 4 with 2-pixel separators.
  const int pw = kSize * 4, gw = 3 * pw + 2 * kAttentionSeparator;
  EpisodeSet set = load_episode_set(dir / "data");
  for (const AttentionFrame& f : r.frames) {
    std::vector<unsigned char> px;
    auto [w, h] = decoded_size(o.out + "/" + f.png, &px);
    ASSERT_EQ(w, gw) << f.png;
    ASSERT_EQ(h, pw) << f.png;
    // The first panel is the current frame in the BEV's colours, each pixel 4 x 4.
    int e = 0;
    while (set.episodes[e].file != f.episode) ++e;
    std::vector<uint8_t> frame(set.frame_values());
    set.planes255(e, f.t, frame.data());
    const std::vector<uint8_t> colour = bev_colour(frame.data(), 8, kSize, kSize);
    for (int y = 0; y < pw; y += 3)
      for (int x = 0; x < pw; x += 5)
        for (int k = 0; k < 3; ++k)
          ASSERT_EQ(px[(y * gw + x) * 3 + k], colour[((y / 4) * kSize + x / 4) * 3 + k]);
    // The separators are white.
    for (int y = 0; y < pw; ++y)
      for (int x : {pw, pw + 1, 2 * pw + 2, 2 * pw + 3}) ASSERT_EQ(px[(y * gw + x) * 3], 255);
  }

  json j = json::parse(test::read_text(o.out + "/attention.json"));
  EXPECT_EQ(j["method"], "bc-oh");
  EXPECT_EQ(j["output"], "throttle_minus_brake");
  EXPECT_EQ(j["feature_map"], json::array({32, 2, 2}));
  ASSERT_EQ(j["channels"].size(), 9u);
  EXPECT_EQ(j["channels"][8], "none");
  ASSERT_EQ(j["frames"].size(), 3u);
  auto check_shares = [](const json& shares, bool allow_zero) {
    double sum = 0, channels = 0;
    for (auto it = shares.begin(); it != shares.end(); ++it) {
      const double v = it.value().get<double>();
      EXPECT_GE(v, 0.0) << it.key();
      EXPECT_LE(v, 1.0) << it.key();
      sum += v;
      if (it.key() != "none") channels += v;
    }
    EXPECT_LE(channels, 1.0 + 1e-9);
    if (!allow_zero || sum > 0) {
      EXPECT_NEAR(sum, 1.0, 1e-9);
    }
  };
  for (const json& f : j["frames"]) {
    for (const char* key : {"png", "episode", "t", "speed", "command", "tl_state", "tl_distance",
                            "output", "action", "module", "map_max", "attention_share",
                            "pixel_share"})
      EXPECT_TRUE(f.contains(key)) << key;
    EXPECT_TRUE(f["tl_state"].is_null());  // the fake episodes record no lights
    check_shares(f["attention_share"], true);
    check_shares(f["pixel_share"], false);
  }
  EXPECT_GE(j["mean"]["frames"].get<int>(), 0);
  check_shares(j["mean"]["attention_share"], true);

  // Same inputs, same bytes; a smaller run into the same folder leaves no older grid behind.
  o.out = dir / "again";
  run_attention(o);
  for (const std::string f : {"attention.json", "attention_000.png", "attention_002.png"})
    EXPECT_EQ(test::read_text(dir / "maps/" + f), test::read_text(dir / "again/" + f)) << f;
  o.frames = 1;
  run_attention(o);
  EXPECT_EQ(test::list_dir(o.out), (std::vector<std::string>{"attention.json", "attention_000.png"}));

  // Stopped frames (speed < 0.5: t % 20 in {0, 1}, t >= 4): t = 20, 21 in each episode.
  o.select = "stopped";
  o.frames = 100;
  r = run_attention(o);
  EXPECT_EQ(r.candidates, 6);
  EXPECT_EQ(r.frames.size(), 6u);
  for (const AttentionFrame& f : r.frames) EXPECT_TRUE(f.t == 20 || f.t == 21) << f.t;

  // Lights need the recorded series.
  o.select = "light";
  EXPECT_THROW(run_attention(o), DataError);
  o.select = "all";
  o.frames = 0;
  EXPECT_THROW(run_attention(o), ConfigError);
}

TEST(Attention, LightFramesFollowTheRecordedTrafficLight) {
  TempDir dir("cd-attention-light");
  const test::FakeEpisodeSpec spec{.frames = 24, .height = kSize, .width = kSize};
  test::fs::create_directories(dir / "data");
  for (int e = 0; e < 3; ++e) {
    EpisodeData d = test::fake_episode(e, spec);
    // A red light 20 m ahead at t in [8, 12), one 50 m ahead at t in [12, 16), none elsewhere.
    for (int t = 0; t < spec.frames; ++t) {
      d.causes["tl_state"].push_back(t >= 8 && t < 16 ? 1.0f : 0.0f);
      d.causes["tl_distance"].push_back(t >= 8 && t < 12 ? 20.0f : t < 16 ? 50.0f : 100.0f);
    }
    write_episode(dir / ("data/" + test::fake_episode_name(e)), test::fake_meta(spec), d);
  }
  const std::string run = train(dir, "bc-so", "so");
  AttentionOptions o;
  o.checkpoint = run;
  o.data = dir / "data";
  o.out = dir / "maps";
  o.select = "light";
  o.frames = 5;
  AttentionReport r = run_attention(o);
  EXPECT_EQ(r.candidates, 3 * 4);
  ASSERT_EQ(r.frames.size(), 5u);
  for (const AttentionFrame& f : r.frames) {
    EXPECT_GE(f.t, 8);
    EXPECT_LT(f.t, 12);
    EXPECT_EQ(f.tl_state, 1.0);
    EXPECT_EQ(f.tl_distance, 20.0);
  }
  // Spread evenly: indices 0, 2, 4, 7, 9 of the 12 candidates (episode order, then t).
  EXPECT_EQ(r.frames[0].t, 8);
  EXPECT_EQ(r.frames[1].t, 10);
  EXPECT_EQ(r.frames[2].episode, test::fake_episode_name(1));
}

}  // namespace
}  // namespace cd
