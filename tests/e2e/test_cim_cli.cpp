// The cim pipeline through the real binary on small hand-made folders: the run folder and its
// stages, series.csv against causes.json and `causaldrive granger`, the pictures, few-shot
// adaptation (--init), the VAE reuse checks, one-line errors. (A tiny cim run in the simulator
// is in test_learned_agents.cpp.)
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../support/fake_episodes.hpp"
#include "../support/tiny_run.hpp"
#include "core/error.hpp"
#include "methods/method.hpp"

namespace cd {
namespace {

using nlohmann::json;
using test::CommandResult;
using test::expect_one_line_error;
using test::read_json;
using test::TempDir;
using test::train_args;

const std::vector<std::string> kChannels = {"drivable", "markings", "route", "vehicles",
                                            "pedestrians", "light_red", "light_green",
                                            "light_yield"};

// 64x64 frames: the road (drivable) always, a lead vehicle box (vehicles) whose gap to the
// ego follows a slow wave per episode, and a speed that follows the gap two steps later.
EpisodeData cim_episode(int episode, int frames) {
  const int S = 64, C = 8;
  EpisodeData d;
  d.channels = C;
  d.height = S;
  d.width = S;
  d.action_dim = 2;
  d.bev_packed.assign(static_cast<size_t>(frames) * S * S, 0);
  std::vector<double> gap;
  for (int t = 0; t < frames; ++t)
    gap.push_back(12 + 10 * std::sin(0.15 * t + episode * 1.3) + 2 * std::sin(0.71 * t * (episode + 1)));
  for (int t = 0; t < frames; ++t) {
    uint8_t* f = d.bev_packed.data() + static_cast<size_t>(t) * S * S;
    for (int y = 0; y < S; ++y)
      for (int x = 26; x < 38; ++x) f[y * S + x] |= 1;  // drivable
    const int ego_row = 48, lead_row = ego_row - static_cast<int>(std::lround(gap[t] / 0.5));
    for (int y = std::max(0, lead_row - 4); y < std::max(0, lead_row + 4); ++y)
      for (int x = 29; x < 35; ++x) f[y * S + x] |= 1 << 3;  // vehicles
    for (int y = ego_row - 4; y < ego_row + 4; ++y)
      for (int x = 29; x < 35; ++x) f[y * S + x] |= 1 << 3;  // the ego is drawn too
    const double speed = std::max(0.0, 0.4 * gap[std::max(0, t - 2)] - 1.0);
    d.speed.push_back(static_cast<float>(speed));
    d.action.insert(d.action.end(), {0.3f, 0.0f});
    d.command.push_back(0);
    d.pose.insert(d.pose.end(), {static_cast<float>(t), 0.0f, 0.0f});
    d.causes["lead_distance"].push_back(static_cast<float>(gap[t]));
    d.causes["lead_present"].push_back(1.0f);
    d.causes["tl_state"].push_back(0.0f);
    d.causes["tl_distance"].push_back(100.0f);
    d.causes["path_free"].push_back(gap[t] > 8 ? 1.0f : 0.0f);
    d.causes["ped_on_path"].push_back(0.0f);
  }
  return d;
}

// noise: [begin, end) steps of every episode whose executed action was injected noise.
void write_cim_folder(const std::string& dir, int episodes, int frames, int first = 0,
                      std::pair<int, int> noise = {0, 0}) {
  test::fs::create_directories(dir);
  test::FakeEpisodeSpec spec;
  spec.height = spec.width = 64;
  EpisodeMeta meta = test::fake_meta(spec);
  meta.channels = kChannels;
  for (int e = 0; e < episodes; ++e) {
    EpisodeData d = cim_episode(first + e, frames);
    d.noise.assign(static_cast<size_t>(frames), 0);
    for (int t = noise.first; t < noise.second; ++t) d.noise[static_cast<size_t>(t)] = 1;
    write_episode(dir + "/" + test::fake_episode_name(e), meta, d);
  }
}

std::string tiny_toml(const std::string& extra = "") {
  return "[vae]\nlatents = 8\nepochs = 1\nbatch_size = 32\nmax_frames = 200\n"
         "\n[cim]\nepochs = 2\nbatch_size = 64\nseries_stride = 2\nmax_causes = 2\nhidden = 16\n"
         "fewshot_steps = 6\n"
         "\n[train]\nthreads = 1\nval_fraction = 0.25\n" + extra;
}

std::pair<uint32_t, uint32_t> png_size(const std::string& path) {
  const std::string b = test::read_text(path);
  EXPECT_GT(b.size(), 24u);
  EXPECT_EQ(b.substr(1, 3), "PNG");
  auto be32 = [&](size_t o) {
    return (uint32_t(uint8_t(b[o])) << 24) | (uint32_t(uint8_t(b[o + 1])) << 16) |
           (uint32_t(uint8_t(b[o + 2])) << 8) | uint32_t(uint8_t(b[o + 3]));
  };
  return {be32(16), be32(20)};
}

struct CimFixture {
  TempDir dir{"cd-cim-cli"};
  std::string config, data, run;
  CimFixture() {
    config = dir / "cim.toml";
    test::write_text(config, tiny_toml());
    data = dir / "data";
    write_cim_folder(data, 4, 80);
    run = dir / "run";
  }
};

TEST(CimCli, PipelineWritesEveryStageAndGrangerReproducesTheTests) {
  CimFixture f;
  CommandResult r = test::run_cli(train_args(f.config, "cim", f.data, f.run));
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  EXPECT_NE(r.out.find("trained cim"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("causes:"), std::string::npos) << r.out;
  EXPECT_EQ(test::list_dir(f.run),
            (std::vector<std::string>{"causaldrive.lock", "causes.json", "granger.png", "predictor.pt",
                                      "predictor_metrics.jsonl", "run.json", "series.csv",
                                      "traversal.png", "vae.pt", "vae_metrics.jsonl"}));
  json run = read_json(f.run + "/run.json");
  EXPECT_EQ(run["method"], "cim");
  EXPECT_EQ(run["stages"], json({"vae", "series", "causes", "predictor", "pictures"}));
  EXPECT_EQ(run["settings"]["vae"]["latents"], 8);
  EXPECT_EQ(run["settings"]["vae"]["beta"], 6.0);
  EXPECT_EQ(run["input"]["view_channels"], json({3}));
  EXPECT_EQ(run["figures"]["vae"]["frames"], 200);
  // One epoch of one at most (patience 0 trains them all); the KL of each latent over the
  // frames it trained on, and the active ones among them (> 0.01 nats).
  const json& vf = run["figures"]["vae"];
  EXPECT_EQ(vf["epochs"], 1);
  EXPECT_EQ(vf["max_epochs"], 1);
  EXPECT_EQ(vf["stopped_early"], false);
  ASSERT_EQ(vf["kl_per_latent"].size(), 8u);
  int active = 0;
  for (const json& k : vf["kl_per_latent"]) {
    EXPECT_GE(k.get<double>(), 0.0);
    active += k.get<double>() > 0.01;
  }
  EXPECT_EQ(vf["active_latents"], active);
  EXPECT_EQ(vf["active_kl_threshold"], 0.01);
  EXPECT_NE(r.out.find(" of 8 latents active (KL > 0.01 nats)"), std::string::npos) << r.out;
  auto vae_lines = test::split_lines(test::read_text(f.run + "/vae_metrics.jsonl"));
  ASSERT_EQ(vae_lines.size(), 1u);
  for (const char* k : {"recon", "kl", "loss", "seconds", "images_per_s"})
    EXPECT_TRUE(json::parse(vae_lines[0])[k].is_number()) << k;

  // series.csv: header, every 2nd frame of the 3 training episodes (the predictor's
  // validation episode is never tested).
  auto lines = test::split_lines(test::read_text(f.run + "/series.csv"));
  ASSERT_EQ(lines.size(), 1u + 3 * 40);
  EXPECT_EQ(lines[0], "episode,speed,z0,z1,z2,z3,z4,z5,z6,z7");
  json causes = read_json(f.run + "/causes.json");
  EXPECT_EQ(causes["target"], "speed");
  EXPECT_EQ(causes["lags"], 3);
  EXPECT_EQ(causes["correction"], "bonferroni");
  EXPECT_EQ(causes["selection"], "partial_r2");
  EXPECT_EQ(causes["rows"], 3 * (40 - 3));
  // The three rules side by side; the run's own rule picks what causes.json selects.
  for (const char* rule : {"bivariate", "conditional", "partial_r2"}) {
    ASSERT_TRUE(causes["rules"].contains(rule)) << rule;
    EXPECT_GE(causes["rules"][rule]["picked"].size(), 1u) << rule;
    EXPECT_LE(causes["rules"][rule]["picked"].size(), 2u) << rule;
  }
  std::vector<int> own;
  for (const auto& p : causes["rules"]["partial_r2"]["picked"]) own.push_back(p["index"]);
  EXPECT_EQ(own, causes["ranked"].get<std::vector<int>>());
  for (const auto& l : causes["latents"])
    EXPECT_EQ(l["significant"].get<bool>(),
              l["partial_r2"].get<double>() >= causes["min_partial_r2"].get<double>());
  ASSERT_EQ(causes["latents"].size(), 8u);
  // Every latent's mean KL on the training episodes; the active ones are those above 0.01.
  EXPECT_EQ(causes["candidates"], "all");
  std::vector<int> active_ones;
  for (const auto& l : causes["latents"])
    if (l["kl"].get<double>() > 0.01) active_ones.push_back(l["index"]);
  EXPECT_EQ(causes["active_latents"].get<std::vector<int>>(), active_ones);
  for (const auto& p : causes["rules"]["bivariate"]["picked"])
    EXPECT_EQ(p["active"].get<bool>(), causes["latents"][p["index"].get<int>()]["kl"].get<double>() > 0.01);
  const auto selected = causes["selected"].get<std::vector<int>>();
  ASSERT_GE(selected.size(), 1u);
  EXPECT_LE(selected.size(), 2u);  // max_causes
  EXPECT_EQ(causes["ground_truth"]["latents"].size(), selected.size());
  for (const auto& g : causes["ground_truth"]["latents"])
    EXPECT_TRUE(g["correlation"].contains("lead_distance"));

  // The CLI's tests on series.csv give the same statistics as causes.json.
  CommandResult g = test::run_cli({"granger", "--input", f.run, "--lags", "3", "--json"});
  ASSERT_TRUE(g.exited && g.exit_code == 0) << g.describe();
  json cli = json::parse(g.out);
  ASSERT_EQ(cli.size(), 8u);
  for (int i = 0; i < 8; ++i) {
    EXPECT_EQ(cli[i]["variable"], "z" + std::to_string(i));
    const double a = cli[i]["p_value"].get<double>(), b = causes["latents"][i]["p_value"].get<double>();
    EXPECT_NEAR(a, b, 1e-9 * std::max(1.0, std::fabs(b))) << i;
    EXPECT_NEAR(cli[i]["f_stat"].get<double>(), causes["latents"][i]["f_stat"].get<double>(),
                1e-6 * std::max(1.0, causes["latents"][i]["f_stat"].get<double>()));
    EXPECT_EQ(cli[i]["df_den"], causes["latents"][i]["df_den"]);
    EXPECT_NEAR(cli[i]["partial_r2"].get<double>(), causes["latents"][i]["partial_r2"].get<double>(),
                1e-9);
  }

  // Pictures: one traversal row per pick (9 cells of 128 px, 2-px separators) and the chart.
  auto [tw, th] = png_size(f.run + "/traversal.png");
  EXPECT_EQ(tw, 9u * 128 + 10 * 2);
  EXPECT_EQ(th, causes["ranked"].size() * 128 + (causes["ranked"].size() + 1) * 2);
  auto [gw, gh] = png_size(f.run + "/granger.png");
  EXPECT_EQ(gw, 2u * 10 + 8 * (6 + 2) + 2);
  EXPECT_EQ(gh, 2u * 10 + 240);

  // Predictor: 2 epochs, samples t >= (3-1)*5 (the history's spacing is the series' by
  // default) and t + 1 < 80 in 3 training episodes.
  EXPECT_EQ(run["settings"]["cim"]["history_stride"], 5);
  EXPECT_EQ(run["figures"]["predictor"]["train_samples"], 3 * (80 - 11));
  EXPECT_EQ(run["figures"]["predictor"]["val_samples"], 80 - 11);
  EXPECT_EQ(test::split_lines(test::read_text(f.run + "/predictor_metrics.jsonl")).size(), 2u);

  // A rerun skips every stage and changes nothing; the same settings in another folder give
  // the same weights.
  const std::string vae = test::read_text(f.run + "/vae.pt");
  const std::string pred = test::read_text(f.run + "/predictor.pt");
  CommandResult again = test::run_cli(train_args(f.config, "cim", f.data, f.run));
  ASSERT_TRUE(again.exited && again.exit_code == 0) << again.describe();
  EXPECT_NE(again.out.find("nothing left to train"), std::string::npos) << again.out;
  EXPECT_EQ(test::read_text(f.run + "/predictor.pt"), pred);
  CommandResult twin = test::run_cli(train_args(f.config, "cim", f.data, f.dir / "twin"));
  ASSERT_TRUE(twin.exited && twin.exit_code == 0) << twin.describe();
  EXPECT_EQ(test::read_text(f.dir / "twin/vae.pt"), vae);
  EXPECT_EQ(test::read_text(f.dir / "twin/series.csv"), test::read_text(f.run + "/series.csv"));
  EXPECT_EQ(test::read_text(f.dir / "twin/predictor.pt"), pred);

  // The agent loads the run; another method's name is refused. It steers a free ego (the
  // default) along the route from the World (the expert's path tracker), a route-mode ego not.
  Settings s;
  EXPECT_TRUE(make_agent("cim", f.run, s)->steers_from_world());
  s.ego.lateral = "route";
  EXPECT_FALSE(make_agent("cim", f.run, s)->steers_from_world());
  EXPECT_THROW(make_agent("cim-mlp", f.run, s), ConfigError);
  EXPECT_THROW(make_agent("cim", f.dir / "nowhere", s), ConfigError);
}

TEST(CimCli, NoisyStepsAreNeverLabelsAndCutTheGrangerSeries) {
  // Steps 20..29 of every episode executed injected noise: speed[t+1] of those t is the
  // noise's motion.
  CimFixture f;
  const std::string noisy = f.dir / "noisy";
  write_cim_folder(noisy, 4, 80, 0, {20, 30});
  CommandResult r = test::run_cli(train_args(f.config, "cim", noisy, f.run));
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  json run = read_json(f.run + "/run.json");
  // Predictor samples t = 10..78 less the 10 noisy steps, per episode (3 train, 1 validation).
  EXPECT_EQ(run["figures"]["predictor"]["train_samples"], 3 * (69 - 10));
  EXPECT_EQ(run["figures"]["predictor"]["val_samples"], 69 - 10);
  // Series rows every 2nd step; t = 22..30 moved under noise since the previous row: left
  // out, and each training episode becomes two segments (t = 0..20 and 32..78).
  auto lines = test::split_lines(test::read_text(f.run + "/series.csv"));
  ASSERT_EQ(lines.size(), 1u + 3 * (11 + 24));
  std::vector<int> segment_rows(6, 0);
  for (size_t i = 1; i < lines.size(); ++i) {
    const int seg = std::stoi(lines[i].substr(0, lines[i].find(',')));
    ASSERT_GE(seg, 0);
    ASSERT_LT(seg, 6);
    ++segment_rows[static_cast<size_t>(seg)];
  }
  EXPECT_EQ(segment_rows, (std::vector<int>{11, 24, 11, 24, 11, 24}));
  EXPECT_EQ(read_json(f.run + "/causes.json")["rows"], 3 * ((11 - 3) + (24 - 3)));
}

// A VAE whose loss rises after its best epoch keeps the best epoch's weights: byte for byte
// those of the same run stopped at that epoch (training is deterministic for a seed).
TEST(CimCli, VaeKeepsTheEpochWithTheLowestLoss) {
  CimFixture f;
  const std::string cfg = f.dir / "spiky.toml";
  test::write_text(cfg, "[vae]\nlatents = 8\nepochs = 4\nbatch_size = 32\nmax_frames = 200\n"
                        "lr = 0.01\n"
                        "\n[cim]\nepochs = 1\nbatch_size = 64\nseries_stride = 2\nhidden = 16\n"
                        "\n[train]\nthreads = 1\nval_fraction = 0.25\n");
  CommandResult r = test::run_cli(train_args(cfg, "cim", f.data, f.run));
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  std::vector<double> losses;
  for (const std::string& l : test::split_lines(test::read_text(f.run + "/vae_metrics.jsonl")))
    losses.push_back(json::parse(l)["loss"].get<double>());
  ASSERT_EQ(losses.size(), 4u);
  const int best = static_cast<int>(std::min_element(losses.begin(), losses.end()) - losses.begin()) + 1;
  ASSERT_LT(best, 4) << "this learning rate no longer makes the loss rise after its best epoch: "
                     << losses[0] << " " << losses[1] << " " << losses[2] << " " << losses[3];
  const json vf = read_json(f.run + "/run.json")["figures"]["vae"];
  EXPECT_EQ(vf["epochs"], 4);
  EXPECT_EQ(vf["kept_epoch"], best);
  EXPECT_EQ(vf["loss"].get<double>(), losses[static_cast<size_t>(best - 1)]);
  EXPECT_NE(r.out.find("kept epoch " + std::to_string(best) + " (lowest loss)"), std::string::npos)
      << r.out;

  const std::string short_cfg = f.dir / "short.toml";
  std::string text = test::read_text(cfg);
  text.replace(text.find("epochs = 4"), 10, "epochs = " + std::to_string(best));
  test::write_text(short_cfg, text);
  const std::string short_run = f.dir / "short";
  ASSERT_EQ(test::run_cli(train_args(short_cfg, "cim", f.data, short_run)).exit_code, 0);
  EXPECT_EQ(read_json(short_run + "/run.json")["figures"]["vae"]["kept_epoch"], best);
  EXPECT_EQ(test::read_text(short_run + "/vae.pt"), test::read_text(f.run + "/vae.pt"));
}

TEST(CimCli, FewShotReusesCausesAndTrainsOnMaxSamples) {
  CimFixture f;
  ASSERT_EQ(test::run_cli(train_args(f.config, "cim", f.data, f.run)).exit_code, 0);
  const std::string other = f.dir / "other";
  write_cim_folder(other, 4, 60, 10);
  const std::string shot = f.dir / "shot";
  CommandResult r = test::run_cli(train_args(f.config, "cim", other, shot,
                                             {"--init", f.run, "--max-samples", "100"}));
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  json run = read_json(shot + "/run.json");
  EXPECT_EQ(run["init"], test::fs::weakly_canonical(f.run).string());
  // The 100 labels are all it uses: no validation split; fewshot_steps = 6 Adam steps in
  // batches of 64 (2 per epoch, 3 epochs), the last weights kept.
  const json& pred = run["figures"]["predictor"];
  EXPECT_EQ(pred["fewshot"], true);
  EXPECT_EQ(pred["labels"], 100);
  EXPECT_EQ(pred["train_samples"], 100);
  EXPECT_EQ(pred["val_samples"], 0);
  EXPECT_EQ(pred["val_episodes"], 0);
  EXPECT_EQ(pred["steps"], 6);
  EXPECT_EQ(pred["kept_epoch"], 3);
  // The summary names the weights it kept (the last epoch's) and their loss, the last line's.
  EXPECT_NE(r.out.find("kept the last epoch 3, training l1 loss"), std::string::npos) << r.out;
  EXPECT_EQ(pred["kept_loss"],
            json::parse(test::split_lines(test::read_text(shot + "/predictor_metrics.jsonl")).back())["train_loss"]);
  EXPECT_EQ(test::read_text(shot + "/vae.pt"), test::read_text(f.run + "/vae.pt"));
  EXPECT_NE(test::read_text(shot + "/predictor.pt"), test::read_text(f.run + "/predictor.pt"));
  json a = read_json(f.run + "/causes.json"), b = read_json(shot + "/causes.json");
  EXPECT_EQ(a["selected"], b["selected"]);
  EXPECT_FALSE(test::fs::exists(shot + "/series.csv"));  // no new selection
  // Epoch 0 is the init predictor on the labels, then the fine-tuning epochs.
  auto lines = test::split_lines(test::read_text(shot + "/predictor_metrics.jsonl"));
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(json::parse(lines[0])["epoch"], 0);
  EXPECT_TRUE(json::parse(lines[0])["train_loss"].is_number());
  EXPECT_FALSE(json::parse(lines[3]).contains("val_loss"));

  expect_one_line_error(test::run_cli(train_args(f.config, "cim", other, f.dir / "x1",
                                                 {"--init", f.dir / "missing"})),
                        "no such run folder");
  expect_one_line_error(test::run_cli(train_args(f.config, "cim-mlp", other, f.dir / "x2",
                                                 {"--init", f.run})),
                        "holds a run of method 'cim'");
}

TEST(CimCli, VaeReuseAndFolderChecksGiveOneLineErrors) {
  CimFixture f;
  ASSERT_EQ(test::run_cli(train_args(f.config, "cim", f.data, f.run)).exit_code, 0);
  // cim-mlp may share cim's VAE (same beta); cim-entangled needs beta 1.
  const std::string mlp = f.dir / "mlp";
  CommandResult r = test::run_cli(train_args(f.config, "cim-mlp", f.data, mlp, {"--vae", f.run}));
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  EXPECT_EQ(test::read_text(mlp + "/vae.pt"), test::read_text(f.run + "/vae.pt"));
  json causes = read_json(mlp + "/causes.json");
  EXPECT_EQ(causes["selected"].size(), 8u);  // all latents
  EXPECT_EQ(read_json(mlp + "/run.json")["figures"]["predictor"]["variables"], 8);
  EXPECT_NO_THROW(make_agent("cim-mlp", mlp, Settings{}));

  expect_one_line_error(test::run_cli(train_args(f.config, "cim-entangled", f.data,
                                                 f.dir / "ent", {"--vae", f.run})),
                        "vae.beta 6");
  expect_one_line_error(test::run_cli(train_args(f.config, "cim-mlp", f.data, f.run)),
                        "holds a run of method 'cim'");
  const std::string other_cfg = f.dir / "other.toml";
  test::write_text(other_cfg, "[vae]\nlatents = 4\nepochs = 1\nmax_frames = 100\n[train]\nthreads = 1\n");
  expect_one_line_error(test::run_cli(train_args(other_cfg, "cim", f.data, f.run)),
                        "other settings");
  // Flushing denormals changes the trained bytes: a run trained without it is not resumed with it.
  const std::string flush_cfg = f.dir / "flush.toml";
  test::write_text(flush_cfg, tiny_toml("flush_denormals = true\n"));
  expect_one_line_error(test::run_cli(train_args(flush_cfg, "cim", f.data, f.run)),
                        "train.flush_denormals false -> true");
  expect_one_line_error(test::run_cli(train_args(f.config, "cim", f.data, f.dir / "y",
                                                 {"--vae", f.data})),
                        "not a cim run folder");
}

}  // namespace
}  // namespace cd
