// Settings from TOML: the shipped quickstart config equals the built-in defaults, and every
// kind of bad input is a ConfigError that names the file and the key.
#include "app/settings.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include <nlohmann/json.hpp>

#include "../support/test_support.hpp"
#include "core/error.hpp"

#ifndef CD_SOURCE_DIR
#error "CD_SOURCE_DIR must be defined by the build"
#endif

namespace cd {
namespace {

using test::TempDir;

// Loads `text` as a config file; returns the ConfigError message ("" when it loaded).
std::string config_error(const std::string& text, std::string* path_out = nullptr) {
  static int counter = 0;
  TempDir dir("cdtest-config");
  const std::string path = dir / ("case" + std::to_string(counter++) + ".toml");
  test::write_text(path, text);
  if (path_out) *path_out = path;
  try {
    load_settings(path);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

bool has(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(ConfigLoad, QuickstartConfigEqualsBuiltInDefaults) {
  const std::string path = std::string(CD_SOURCE_DIR) + "/configs/quickstart.toml";
  Settings s = load_settings(path);
  EXPECT_EQ(s.source, path);
  EXPECT_EQ(Settings{}.source, "(built-in defaults)");
  const nlohmann::json loaded = settings_to_json(s), defaults = settings_to_json(Settings{});
  EXPECT_EQ(loaded, defaults) << "diff (defaults -> quickstart.toml): "
                              << nlohmann::json::diff(defaults, loaded).dump(2);
  EXPECT_FALSE(loaded.contains("source"));
}

TEST(ConfigLoad, PredictorHistoryHasTheGrangerSeriesSpacingByDefault) {
  // The causes are tested on lags series_stride steps apart; the predictor that uses them sees
  // its history at the same spacing (seed 000's public agent: 3 values 5 steps apart).
  const Settings s;
  EXPECT_EQ(s.cim.history_stride, s.cim.series_stride);
  EXPECT_EQ(s.cim.series_stride, 5);
  const Settings paper = load_settings(std::string(CD_SOURCE_DIR) + "/configs/cim_paper.toml");
  EXPECT_EQ(paper.cim.history_stride, paper.cim.series_stride);
  // Both stay configurable, each on its own.
  const std::string dir = ::testing::TempDir();
  const std::string path = dir + "/spacing.toml";
  std::FILE* f = std::fopen(path.c_str(), "w");
  ASSERT_NE(f, nullptr);
  std::fputs("[cim]\nseries_stride = 2\nhistory_stride = 3\nselection = \"conditional\"\n", f);
  std::fclose(f);
  const Settings own = load_settings(path);
  EXPECT_EQ(own.cim.series_stride, 2);
  EXPECT_EQ(own.cim.history_stride, 3);
  EXPECT_EQ(own.cim.selection, "conditional");
}

TEST(ConfigLoad, JsonCoversEverySection) {
  const nlohmann::json j = settings_to_json(Settings{});
  for (const char* section : {"world", "ego", "bev", "expert", "collect"})
    EXPECT_TRUE(j.contains(section)) << section;
  EXPECT_EQ(j["world"]["town"], "town-a");
  EXPECT_EQ(j["collect"]["noise"]["enabled"], false);
}

TEST(ConfigLoad, EmptyFileGivesDefaultsAndPartialFileChangesOnlyItsKeys) {
  TempDir dir("cdtest-config");
  const std::string empty = dir / "empty.toml";
  test::write_text(empty, "# nothing here\n");
  EXPECT_EQ(settings_to_json(load_settings(empty)), settings_to_json(Settings{}));

  const std::string partial = dir / "partial.toml";
  test::write_text(partial,
                   "[world]\ntraffic = \"dense\"\nwarmup_s = 5\n"  // an integer for a number
                   "[world.density.dense]\ncars_per_km = 12.5\n"
                   "[bev]\nheight = 96\n"
                   "[collect.noise]\nenabled = true\n");
  Settings s = load_settings(partial);
  Settings want;
  want.world.traffic = "dense";
  want.world.warmup_s = 5;
  want.world.dense.cars_per_km = 12.5;
  want.bev.height = 96;
  want.collect.noise.enabled = true;
  EXPECT_EQ(settings_to_json(s), settings_to_json(want));
  EXPECT_EQ(traffic_density(s.world).cars_per_km, 12.5);
}

TEST(ConfigLoad, TestSupportConfigLoads) {
  TempDir dir("cdtest-config");
  Settings s = load_settings(test::write_test_config(dir, "regular"));
  EXPECT_EQ(s.world.town, "town-a");
  EXPECT_EQ(s.world.traffic, "regular");
  EXPECT_EQ(s.world.warmup_s, 5.0);
  EXPECT_EQ(s.collect.min_route_m, 100.0);
  EXPECT_EQ(s.collect.max_route_m, 200.0);
}

TEST(ConfigErrors, MissingFile) {
  try {
    load_settings("/nonexistent/dir/config.toml");
    FAIL() << "a missing file loaded";
  } catch (const ConfigError& e) {
    std::string msg = e.what();
    EXPECT_TRUE(has(msg, "not found")) << msg;
    EXPECT_TRUE(has(msg, "/nonexistent/dir/config.toml")) << msg;
  }
}

TEST(ConfigErrors, MalformedTomlNamesFileAndLine) {
  std::string path;
  std::string msg = config_error("[world]\ntown = \"town-a\"\ntraffic = = \"dense\"\n", &path);
  ASSERT_FALSE(msg.empty()) << "malformed TOML loaded";
  EXPECT_TRUE(has(msg, path)) << msg;
  EXPECT_TRUE(has(msg, path + ":3") || has(msg, "line 3")) << "should point at line 3: " << msg;

  msg = config_error("[world\n", &path);
  ASSERT_FALSE(msg.empty());
  EXPECT_TRUE(has(msg, path + ":1") || has(msg, "line 1")) << msg;

  msg = config_error("[collect]\nepisodes = 2\n[collect]\nseed = 1\n", &path);  // table twice
  ASSERT_FALSE(msg.empty()) << "a redefined table loaded";
  EXPECT_TRUE(has(msg, path)) << msg;
}

TEST(ConfigErrors, UnknownKeysAreNamedWithTheirPath) {
  struct Case {
    const char* text;
    const char* key;
  };
  const Case cases[] = {
      {"townn = \"town-a\"\n", "townn"},
      {"[world]\ntownn = \"town-a\"\n", "world.townn"},
      {"[collect.noise]\nfoo = 1\n", "collect.noise.foo"},
      {"[world.density.regular]\ncars_per_kmm = 3\n", "world.density.regular.cars_per_kmm"},
      {"[world.density.heavy]\ncars_per_km = 3\n", "world.density.heavy"},
      {"[wrld]\ntown = \"town-a\"\n", "wrld"},
      {"[ego]\nmax_accel = 3.0\nmax_acel = 3.0\n", "ego.max_acel"},
      {"[bev]\nchannels = 8\n", "bev.channels"},
  };
  for (const Case& c : cases) {
    std::string path;
    std::string msg = config_error(c.text, &path);
    ASSERT_FALSE(msg.empty()) << "unknown key " << c.key << " was accepted";
    EXPECT_TRUE(has(msg, c.key)) << "should name " << c.key << ": " << msg;
    EXPECT_TRUE(has(msg, path)) << "should name the file: " << msg;
    EXPECT_TRUE(has(msg, "unknown")) << msg;
  }
}

TEST(ConfigErrors, WrongTypesAreNamed) {
  struct Case {
    const char* text;
    const char* key;
  };
  const Case cases[] = {
      {"[world]\ndt = \"fast\"\n", "world.dt"},
      {"[world]\ntown = 3\n", "world.town"},
      {"[collect]\nepisodes = 2.5\n", "collect.episodes"},
      {"[collect]\nepisodes = \"two\"\n", "collect.episodes"},
      {"[collect.noise]\nenabled = 1\n", "collect.noise.enabled"},
      {"[bev]\nheight = [64]\n", "bev.height"},
      {"world = 3\n", "world"},
      {"[ego]\nlength = true\n", "ego.length"},
  };
  for (const Case& c : cases) {
    std::string path;
    std::string msg = config_error(c.text, &path);
    ASSERT_FALSE(msg.empty()) << "wrong type for " << c.key << " was accepted";
    EXPECT_TRUE(has(msg, c.key)) << "should name " << c.key << ": " << msg;
    EXPECT_TRUE(has(msg, path)) << "should name the file: " << msg;
  }
}

TEST(ConfigErrors, OutOfRangeValuesAreNamed) {
  struct Case {
    const char* text;
    const char* key;
  };
  const Case cases[] = {
      {"[world]\ndt = 0\n", "world.dt"},
      {"[world]\ndt = 5.0\n", "world.dt"},
      {"[world]\nwarmup_s = -1\n", "world.warmup_s"},
      {"[ego]\nmax_speed = -1\n", "ego.max_speed"},
      {"[bev]\nheight = 4\n", "bev.height"},
      {"[bev]\nego_row_fraction = 1.5\n", "bev.ego_row_fraction"},
      {"[collect]\nworkers = 0\n", "collect.workers"},
      {"[collect]\nepisodes = -3\n", "collect.episodes"},
      {"[collect]\nseed = -1\n", "collect.seed"},
      {"[world.density.dense]\npeds_per_km = -2\n", "world.density.dense.peds_per_km"},
      {"[world]\ndt = nan\n", "world.dt"},
      {"[world]\nview_radius = inf\n", "world.view_radius"},
      {"[world]\nped_ahead_m = -1\n", "world.ped_ahead_m"},
      {"[collect]\nhold_s = -0.5\n", "collect.hold_s"},
      {"[train]\nsituation_weights = \"inverse\"\n", "train.situation_weights"},
      {"[train]\nsituation_weight_max = 0.5\n", "train.situation_weight_max"},
      {"[model]\npedals = \"three\"\n", "model.pedals"},
  };
  for (const Case& c : cases) {
    std::string path;
    std::string msg = config_error(c.text, &path);
    ASSERT_FALSE(msg.empty()) << "out-of-range " << c.text << " was accepted";
    EXPECT_TRUE(has(msg, c.key)) << "should name " << c.key << ": " << msg;
    EXPECT_TRUE(has(msg, path)) << "should name the file: " << msg;
  }
}

TEST(ConfigErrors, TrafficLevelListsAllowedValues) {
  std::string path;
  std::string msg = config_error("[world]\ntraffic = \"heavy\"\n", &path);
  ASSERT_FALSE(msg.empty()) << "traffic = heavy was accepted";
  EXPECT_TRUE(has(msg, "world.traffic")) << msg;
  EXPECT_TRUE(has(msg, "heavy")) << msg;
  for (const char* allowed : {"empty", "regular", "dense"})
    EXPECT_TRUE(has(msg, allowed)) << "should list " << allowed << ": " << msg;
}

TEST(ConfigErrors, EvalSensorIsCleanOrShiftedAndItsStrengthsAreInRange) {
  Settings defaults;
  EXPECT_EQ(defaults.eval.sensor, "clean") << "every eval is clean unless asked";
  std::string path;
  std::string msg = config_error("[eval]\nsensor = \"foggy\"\n", &path);
  ASSERT_FALSE(msg.empty()) << "sensor = foggy was accepted";
  EXPECT_EQ(msg.find('\n'), std::string::npos) << "one line: " << msg;
  EXPECT_TRUE(has(msg, "eval.sensor")) << msg;
  EXPECT_TRUE(has(msg, "foggy")) << msg;
  EXPECT_TRUE(has(msg, "clean") && has(msg, "shifted")) << msg;
  EXPECT_TRUE(has(msg, path)) << msg;
  for (const char* bad : {"sensor_miss = 1.5", "sensor_fade = -0.1", "sensor_ghosts = 50",
                          "sensor_jitter_m = -1", "sensor_seed = -3"}) {
    msg = config_error(std::string("[eval]\n") + bad + "\n");
    const std::string key = std::string("eval.") + std::string(bad).substr(0, std::string(bad).find(' '));
    EXPECT_TRUE(has(msg, key)) << bad << ": " << msg;
  }
  msg = config_error("[eval]\nsensor_mis = 0.2\n");
  EXPECT_TRUE(has(msg, "eval.sensor_mis") && has(msg, "unknown")) << msg;

  TempDir dir("cdtest-config");
  const std::string ok = dir / "shifted.toml";
  test::write_text(ok, "[eval]\nsensor = \"shifted\"\nsensor_seed = 7\nsensor_miss = 0.3\n"
                       "sensor_jitter_m = 1.0\nsensor_ghosts = 2\nsensor_fade = 0.6\n");
  Settings s = load_settings(ok);
  EXPECT_EQ(s.eval.sensor, "shifted");
  EXPECT_EQ(s.eval.sensor_shift.seed, 7u);
  EXPECT_EQ(s.eval.sensor_shift.miss, 0.3);
  EXPECT_EQ(s.eval.sensor_shift.jitter_m, 1.0);
  EXPECT_EQ(s.eval.sensor_shift.ghosts, 2.0);
  EXPECT_EQ(s.eval.sensor_shift.fade, 0.6);
  // The same list writes and reads them back.
  Settings back = settings_from_json(settings_to_json(s), "record");
  EXPECT_EQ(settings_to_json(back), settings_to_json(s));
  EXPECT_EQ(back.eval.sensor, "shifted");
}

TEST(ConfigErrors, SenseViewIsBevOrCamera) {
  EXPECT_EQ(Settings{}.view, "bev") << "the BEV unless asked";
  std::string path;
  const std::string msg = config_error("[sense]\nview = \"lidar\"\n", &path);
  ASSERT_FALSE(msg.empty()) << "view = lidar was accepted";
  EXPECT_EQ(msg.find('\n'), std::string::npos) << "one line: " << msg;
  EXPECT_TRUE(has(msg, "sense.view") && has(msg, "lidar")) << msg;
  EXPECT_TRUE(has(msg, "bev") && has(msg, "camera")) << msg;
  TempDir dir("cdtest-config");
  const std::string ok = dir / "camera.toml";
  test::write_text(ok, "[sense]\nview = \"camera\"\n\n[sense.camera]\nwidth = 200\nheight = 88\n");
  const Settings s = load_settings(ok);
  EXPECT_EQ(s.view, "camera");
  EXPECT_EQ(s.camera.width, 200);
  EXPECT_EQ(frame_format_of(s).bytes(), 3u * 200 * 88);
  EXPECT_EQ(settings_from_json(settings_to_json(s), "record").view, "camera");
}

TEST(ConfigErrors, InconsistentRangesAreRejected) {
  std::string msg = config_error("[collect]\nmin_route_m = 500\nmax_route_m = 200\n");
  EXPECT_TRUE(has(msg, "max_route_m")) << msg;
  msg = config_error("[collect.noise]\nmin_s = 2.0\nmax_s = 1.0\n");
  EXPECT_TRUE(has(msg, "max_s")) << msg;
}

// [mujoco]: per-env episode counts, noise windows, and the one-line errors of its keys.
TEST(ConfigLoad, MujocoTableReadsPerEnvCounts) {
  TempDir dir("cdtest-config");
  const std::string path = dir / "mj.toml";
  test::write_text(path,
                   "[mujoco]\nsize = 48\neval_episodes = 3\n"
                   "[mujoco.episodes]\nant = 7\nhumanoid = 200\n"
                   "[mujoco.noise]\nenabled = true\nsigma = 0.1\n"
                   "[model]\nhead = \"linear\"\n[train]\nweight_decay = 0.03\n");
  const Settings s = load_settings(path);
  EXPECT_EQ(s.mujoco.size, 48);
  EXPECT_EQ(s.mujoco.eval_episodes, 3);
  EXPECT_EQ(s.mujoco.episodes.of("ant"), 7);
  EXPECT_EQ(s.mujoco.episodes.of("humanoid"), 200);
  EXPECT_EQ(s.mujoco.episodes.of("reacher"), Settings{}.mujoco.episodes.reacher);
  EXPECT_TRUE(s.mujoco.noise.enabled);
  EXPECT_EQ(s.mujoco.noise.sigma, 0.1);
  EXPECT_EQ(s.model.head, "linear");
  EXPECT_EQ(s.train.weight_decay, 0.03);
  EXPECT_THROW(s.mujoco.episodes.of("walker"), ConfigError);
  // The record's JSON reads back to the same settings.
  EXPECT_EQ(settings_to_json(settings_from_json(settings_to_json(s), "record")), settings_to_json(s));
}

TEST(ConfigErrors, MujocoKeysAreChecked) {
  std::string msg = config_error("[mujoco.episodes]\nwalker = 3\n");
  EXPECT_TRUE(has(msg, "walker")) << msg;
  msg = config_error("[mujoco.episodes]\nant = 0\n");
  EXPECT_TRUE(has(msg, "mujoco.episodes.ant")) << msg;
  msg = config_error("[mujoco.noise]\nmin_steps = 9\nmax_steps = 3\n");
  EXPECT_TRUE(has(msg, "mujoco.noise.max_steps")) << msg;
  msg = config_error("[model]\nhead = \"mlp\"\n");
  EXPECT_TRUE(has(msg, "model.head")) << msg;
  msg = config_error("[mujoco]\nplanner_smoothing = 1.0\n");
  EXPECT_TRUE(has(msg, "mujoco.planner_smoothing")) << msg;
  msg = config_error("[mujoco]\nplanner_sigma = -0.5\n");
  EXPECT_TRUE(has(msg, "mujoco.planner_sigma")) << msg;
}

// The Python module's settings dict: keys set over a base, unknown keys and bad values refused
// with the key named, other keys kept from the base.
TEST(ConfigOverride, SetsKeysOverTheBaseAndRefusesUnknownOnes) {
  Settings base;
  base.world.warmup_s = 7;
  Settings s = override_settings(base, "world.traffic = \"dense\"\neval.trials = 2\n"
                                       "world.density.dense.cars_per_km = 40.5\n", "settings");
  EXPECT_EQ(s.world.traffic, "dense");
  EXPECT_EQ(s.eval.trials, 2);
  EXPECT_DOUBLE_EQ(s.world.dense.cars_per_km, 40.5);
  EXPECT_DOUBLE_EQ(s.world.warmup_s, 7);  // kept from the base
  EXPECT_EQ(base.world.traffic, Settings{}.world.traffic);
  auto message = [&](const std::string& toml) {
    try {
      override_settings(base, toml, "settings");
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("world.trafic = \"dense\"\n").find("world.trafic"), std::string::npos);
  EXPECT_NE(message("world.traffic = \"jammed\"\n").find("world.traffic"), std::string::npos);
  EXPECT_NE(message("world.dt = 5.0\n").find("world.dt"), std::string::npos);
  EXPECT_NE(message("collect.min_route_m = 900.0\ncollect.max_route_m = 100.0\n")
                .find("max_route_m"), std::string::npos);
  EXPECT_NE(message("world.traffic = \n").find("settings"), std::string::npos);
}

}  // namespace
}  // namespace cd
