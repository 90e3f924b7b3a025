// Granger causality (SPEC section 4): granger_f_test, adjust_p_values and `causaldrive granger`
// against statsmodels (grangercausalitytests, OLS on hand-assembled per-episode designs,
// multipletests) run by the oracle Python.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "causal/granger.hpp"
#include "cli/commands.hpp"
#include "core/error.hpp"
#include "../support/test_support.hpp"

namespace cd {
namespace {

using json = nlohmann::json;
using test::CommandResult;
using test::TempDir;
using Series = std::vector<std::vector<double>>;

// Relative closeness (exact zeros compare equal).
void expect_rel(double a, double b, double tol, const std::string& what) {
  EXPECT_LE(std::abs(a - b), tol * std::max(std::abs(a), std::abs(b))) << what << ": " << a
                                                                      << " vs " << b;
}

std::string expect_one_line_error(const CommandResult& r, const std::string& needle) {
  EXPECT_TRUE(r.exited && r.exit_code == 1) << r.describe();
  auto lines = test::split_lines(r.err);
  EXPECT_EQ(lines.size(), 1u) << r.describe();
  EXPECT_NE(r.err.find(needle), std::string::npos) << "want '" << needle << "' in " << r.describe();
  EXPECT_TRUE(r.out.empty()) << r.describe();
  return lines.empty() ? "" : lines[0];
}

// Synthetic episodes: y depends on lagged x1 (and its own lag), x2 is noise, x3 is a noisy
// copy of lagged y (no cause of y). Each episode gets its own level shift in y and x1, so that
// lags taken across a boundary would change the regressions noticeably.
struct Data {
  std::vector<std::string> episode_ids;
  std::map<std::string, Series> cols;  // y, x1, x2, x3
};

Data make_data(const std::vector<int>& lengths, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  Data d;
  for (size_t e = 0; e < lengths.size(); ++e) {
    const int T = lengths[e];
    const double shift = 4.0 * static_cast<double>(e % 3) - 3.0;
    std::vector<double> y(T), x1(T), x2(T), x3(T);
    for (int t = 0; t < T; ++t) {
      x1[t] = shift + noise(rng);
      x2[t] = noise(rng);
      y[t] = 0.5 * shift + noise(rng);
      if (t >= 3) y[t] += 0.3 * (y[t - 1] - 0.5 * shift) + 0.35 * (x1[t - 2] - shift) +
                          0.15 * (x1[t - 3] - shift);
      x3[t] = (t >= 1 ? 0.5 * y[t - 1] : 0.0) + noise(rng);
    }
    d.episode_ids.push_back("run-" + std::string(1, static_cast<char>('a' + e)));
    d.cols["y"].push_back(y);
    d.cols["x1"].push_back(x1);
    d.cols["x2"].push_back(x2);
    d.cols["x3"].push_back(x3);
  }
  return d;
}

// CSV with full-precision numbers; with_episode adds a leading "episode" column.
std::string write_csv(const TempDir& dir, const std::string& name, const Data& d,
                      bool with_episode) {
  std::string text = with_episode ? "episode,y,x1,x2,x3\n" : "y,x1,x2,x3\n";
  char buf[64];
  for (size_t e = 0; e < d.episode_ids.size(); ++e) {
    for (size_t t = 0; t < d.cols.at("y")[e].size(); ++t) {
      if (with_episode) text += d.episode_ids[e] + ",";
      const char* sep = "";
      for (const char* c : {"y", "x1", "x2", "x3"}) {
        std::snprintf(buf, sizeof buf, "%s%.17g", sep, d.cols.at(c)[e][t]);
        text += buf;
        sep = ",";
      }
      text += "\n";
    }
  }
  const std::string path = dir / name;
  test::write_text(path, text);
  return path;
}

json run_json(const std::vector<std::string>& args) {
  CommandResult r = test::run_cli(args);
  EXPECT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  return json::parse(r.out);  // throws (test fails) if stdout holds anything but the array
}

// The oracle, one Python run for all jobs (importing statsmodels takes most of its time):
//   bivariate(CSV, L, VARS)           grangercausalitytests(column_stack([y, x]), L)[L][0]['ssr_ftest']
//   episodes(CSV, EPCOL, L, COND, VARS)  per-episode lagged design, sm.OLS (COND: each variable
//                                     conditioned on the other listed ones), and the naive
//                                     (boundary-ignoring) grangercausalitytests F
//   multitest(ALPHA, P)               multipletests bonferroni and fdr_bh
const char* kOracle = R"py(
import sys, json, csv
import numpy as np
import scipy.stats
import statsmodels.api as sm
import inspect
from statsmodels.tsa.stattools import grangercausalitytests
from statsmodels.stats.multitest import multipletests

def read(path, ep_col=None):
    with open(path) as f:
        rows = list(csv.reader(f))
    head, body = rows[0], rows[1:]
    cols = {h: [r[i] for r in body] for i, h in enumerate(head)}
    eps = []  # list of dict col -> array, consecutive runs of the episode value
    if ep_col:
        ids = cols.pop(ep_col)
        start = 0
        for i in range(1, len(ids) + 1):
            if i == len(ids) or ids[i] != ids[start]:
                eps.append({k: np.array([float(v) for v in c[start:i]]) for k, c in cols.items()})
                start = i
    else:
        eps.append({k: np.array([float(v) for v in c]) for k, c in cols.items()})
    return eps

def ssr(Y, X):
    return sm.OLS(Y, sm.add_constant(X, has_constant='add')).fit().ssr

def design(eps, L, regs):
    Ys, Xs = [], []
    for ep in eps:
        T = len(ep['y'])
        if T <= L:
            continue
        Ys.append(ep['y'][L:])
        Xs.append(np.column_stack([ep[v][L - j:T - j] for v in regs for j in range(1, L + 1)]))
    return np.concatenate(Ys), np.vstack(Xs)

def granger(data, L):
    # statsmodels deprecated `verbose` (0.14) and later removed it; older ones print without it.
    params = inspect.signature(grangercausalitytests).parameters
    quiet = {'verbose': False} if 'verbose' in params else {}
    return grangercausalitytests(data, maxlag=L, **quiet)

def bivariate(path, L, names):
    ep, out = read(path)[0], {}
    for x in names:
        res = granger(np.column_stack([ep['y'], ep[x]]), L)
        F, p, df_den, df_num = res[L][0]['ssr_ftest']
        out[x] = {'f': float(F), 'p': float(p), 'df_den': int(df_den), 'df_num': int(df_num)}
    return out

def episodes(path, ep_col, L, cond, names):
    eps, out = read(path, ep_col), {}
    whole = {k: np.concatenate([e[k] for e in eps]) for k in eps[0]}  # boundaries ignored
    for x in names:
        base = ['y'] + ([v for v in names if v != x] if cond else [])
        Y, Xr = design(eps, L, base)
        _, Xu = design(eps, L, base + [x])
        ssr_r, ssr_u = ssr(Y, Xr), ssr(Y, Xu)
        n, k_u = len(Y), Xu.shape[1] + 1
        F = ((ssr_r - ssr_u) / L) / (ssr_u / (n - k_u))
        naive = granger(np.column_stack([whole['y'], whole[x]]), L)
        out[x] = {'f': F, 'p': float(scipy.stats.f.sf(F, L, n - k_u)), 'df_den': n - k_u,
                  'df_num': L, 'rows': n, 'naive_f': float(naive[L][0]['ssr_ftest'][0])}
    return out

def multitest(alpha, p):
    out = {}
    for name, method in (('bonferroni', 'bonferroni'), ('bh', 'fdr_bh')):
        reject, adj, _, _ = multipletests(p, alpha=alpha, method=method)
        out[name] = {'adj': [float(v) for v in adj], 'reject': [bool(v) for v in reject]}
    return out

# argv[1]: a JSON object, job name -> [function name, arguments...]
with open(sys.argv[1]) as f:
    jobs = json.load(f)
out = {name: globals()[job[0]](*job[1:]) for name, job in jobs.items()}
print(json.dumps(out))
)py";

const std::vector<std::string> kVars = {"x1", "x2", "x3"};
const std::vector<double> kP = {0.01, 0.04, 0.03, 0.2, 0.001, 0.04, 0.9, 0.5, 0.0123, 1.0};
constexpr double kAlpha = 0.05;

// The tests' data sets, their CSV files and the oracle's answers, made once per process.
struct Shared {
  TempDir dir{"cd-granger"};
  Data one = make_data({500}, 11);                  // one episode
  Data eps = make_data({150, 2, 220, 130, 90}, 23);  // the 2-row episode is shorter than L+1
  Data cond = make_data({160, 210, 140}, 5);
  std::string one_csv, eps_csv, cond_csv;
  json oracle;

  Shared() {
    one_csv = write_csv(dir, "one.csv", one, false);
    eps_csv = write_csv(dir, "eps.csv", eps, true);
    cond_csv = write_csv(dir, "cond.csv", cond, true);
    json jobs = json::object();
    jobs["one"] = json::array({"bivariate", one_csv, 3, kVars});
    jobs["eps"] = json::array({"episodes", eps_csv, "episode", 3, false, kVars});
    jobs["cond"] = json::array({"episodes", cond_csv, "episode", 2, true, kVars});
    jobs["multitest"] = json::array({"multitest", kAlpha, kP});
    test::write_text(dir / "jobs.json", jobs.dump());
    CommandResult r = test::run_python(kOracle, {dir / "jobs.json"}, dir);
    if (!(r.exited && r.exit_code == 0)) throw std::runtime_error("oracle failed: " + r.describe());
    oracle = json::parse(r.out);
  }
};

const Shared& shared() {
  static Shared s;
  return s;
}

TEST(GrangerCli, BivariateMatchesStatsmodels) {
  const Shared& sh = shared();
  const Data& d = sh.one;
  const std::string& csv = sh.one_csv;
  json got = run_json({"granger", "--input", csv, "--target", "y", "--lags", "3", "--json"});
  const json& want = sh.oracle["one"];
  ASSERT_TRUE(got.is_array());
  ASSERT_EQ(got.size(), 3u) << got.dump();
  for (size_t i = 0; i < kVars.size(); ++i) {
    const json& g = got[i];
    const json& w = want[kVars[i]];
    EXPECT_EQ(g["variable"], kVars[i]);
    for (const char* key : {"variable", "f_stat", "p_value", "p_adjusted", "df_num", "df_den",
                            "selected"})
      EXPECT_TRUE(g.contains(key)) << key << " in " << g.dump();
    expect_rel(g["f_stat"].get<double>(), w["f"].get<double>(), 1e-8, kVars[i] + " F");
    expect_rel(g["p_value"].get<double>(), w["p"].get<double>(), 1e-8, kVars[i] + " p");
    EXPECT_EQ(g["df_num"].get<int>(), w["df_num"].get<int>());
    EXPECT_EQ(g["df_den"].get<int>(), w["df_den"].get<int>());
    EXPECT_EQ(g["df_den"].get<int>(), 500 - 3 - 2 * 3 - 1);
    EXPECT_EQ(g["p_adjusted"].get<double>(), g["p_value"].get<double>());  // correction none
  }
  // x1 drives y; x2 is noise.
  EXPECT_TRUE(got[0]["selected"].get<bool>()) << got.dump();
  EXPECT_LT(got[0]["p_value"].get<double>(), 1e-6);
  EXPECT_FALSE(got[1]["selected"].get<bool>()) << got.dump();

  // The library call gives the same numbers as the binary.
  GrangerTest t = granger_f_test(d.cols.at("y"), d.cols.at("x1"), 3);
  expect_rel(t.f_stat, want["x1"]["f"].get<double>(), 1e-8, "granger_f_test F");
  expect_rel(t.p_value, want["x1"]["p"].get<double>(), 1e-8, "granger_f_test p");
  EXPECT_EQ(t.df_num, 3);
  EXPECT_EQ(t.df_den, 490);
  EXPECT_EQ(t.rows, 497);

  // The readable table: one row per variable, x1 marked, and the summary line.
  CommandResult r = test::run_cli({"granger", "-i", csv, "--target", "y", "--variables", "x1,x2"});
  ASSERT_TRUE(r.exited && r.exit_code == 0) << r.describe();
  auto lines = test::split_lines(r.out);
  ASSERT_EQ(lines.size(), 5u) << r.out;
  EXPECT_TRUE(test::starts_with(lines[2], "x1") && test::ends_with(lines[2], "*")) << r.out;
  EXPECT_TRUE(test::starts_with(lines[3], "x2") && !test::ends_with(lines[3], "*")) << r.out;
  EXPECT_EQ(lines[4], "selected: 1 of 2 at alpha 0.05 (correction none)") << r.out;
}

TEST(GrangerCli, EpisodesNeverLagAcrossBoundaries) {
  const Shared& sh = shared();
  const Data& d = sh.eps;
  const std::string& csv = sh.eps_csv;
  TempDir dir("cd-granger");
  json got = run_json({"granger", "--input", csv, "--target", "y", "--episode-col", "episode",
                       "--json"});
  const json& want = sh.oracle["eps"];
  ASSERT_EQ(got.size(), 3u) << got.dump();
  const long rows = (150 - 3) + (220 - 3) + (130 - 3) + (90 - 3);
  for (size_t i = 0; i < kVars.size(); ++i) {
    const json& g = got[i];
    const json& w = want[kVars[i]];
    EXPECT_EQ(w["rows"].get<long>(), rows);
    expect_rel(g["f_stat"].get<double>(), w["f"].get<double>(), 1e-8, kVars[i] + " F");
    expect_rel(g["p_value"].get<double>(), w["p"].get<double>(), 1e-8, kVars[i] + " p");
    EXPECT_EQ(g["df_den"].get<long>(), rows - 2 * 3 - 1);
    EXPECT_EQ(g["df_num"].get<int>(), 3);
    // Ignoring the boundaries (one long series) gives a different statistic.
    const double naive = w["naive_f"].get<double>();
    EXPECT_GT(std::abs(g["f_stat"].get<double>() - naive), 1e-3 * naive) << kVars[i];
  }
  // The short episode really contributes nothing: the library agrees without it.
  Series y = d.cols.at("y"), x = d.cols.at("x1");
  y.erase(y.begin() + 1);
  x.erase(x.begin() + 1);
  GrangerTest t = granger_f_test(y, x, 3);
  expect_rel(t.f_stat, got[0]["f_stat"].get<double>(), 1e-12, "without the short episode");
  EXPECT_EQ(t.rows, rows);

  // A run folder: DIR/series.csv with the defaults --target speed --episode-col episode.
  std::string text = test::read_text(csv);
  text.replace(0, text.find('\n'), "episode,speed,x1,x2,x3");
  std::filesystem::create_directories(dir / "run");
  test::write_text(dir / "run/series.csv", text);
  json from_dir = run_json({"granger", "--input", dir / "run", "--json"});
  ASSERT_EQ(from_dir.size(), 3u) << from_dir.dump();
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(from_dir[i]["variable"], got[i]["variable"]);
    EXPECT_EQ(from_dir[i]["f_stat"].get<double>(), got[i]["f_stat"].get<double>());
  }
}

TEST(GrangerCli, ConditionalMatchesHandAssembledOls) {
  const Shared& sh = shared();
  const Data& d = sh.cond;
  json got = run_json({"granger", "--input", sh.cond_csv, "--target", "y", "--episode-col",
                       "episode", "--lags", "2", "--conditional", "--json"});
  const json& want = sh.oracle["cond"];
  ASSERT_EQ(got.size(), 3u) << got.dump();
  const long rows = (160 - 2) + (210 - 2) + (140 - 2);
  for (size_t i = 0; i < kVars.size(); ++i) {
    const json& g = got[i];
    const json& w = want[kVars[i]];
    expect_rel(g["f_stat"].get<double>(), w["f"].get<double>(), 1e-8, kVars[i] + " F");
    expect_rel(g["p_value"].get<double>(), w["p"].get<double>(), 1e-8, kVars[i] + " p");
    // k_u = 1 + 2 lags * (y + 2 others + the candidate) = 9 regressors.
    EXPECT_EQ(g["df_den"].get<long>(), rows - 9);
    EXPECT_EQ(w["df_den"].get<long>(), rows - 9);
  }
  // The library call, conditioning x2 on x1 and x3.
  GrangerTest t = granger_f_test(d.cols.at("y"), d.cols.at("x2"), 2,
                                 {d.cols.at("x1"), d.cols.at("x3")});
  expect_rel(t.f_stat, want["x2"]["f"].get<double>(), 1e-8, "conditional granger_f_test F");
  EXPECT_EQ(t.df_den, rows - 9);
  // Conditioning changes the statistic relative to the bivariate test.
  GrangerTest b = granger_f_test(d.cols.at("y"), d.cols.at("x2"), 2);
  EXPECT_GT(std::abs(b.f_stat - t.f_stat), 1e-6 * t.f_stat);
}

TEST(GrangerCorrections, MatchMultipletests) {
  const Shared& sh = shared();
  const std::vector<double>& p = kP;
  const double alpha = kAlpha;
  const json& want = sh.oracle["multitest"];
  EXPECT_EQ(adjust_p_values(p, "none"), p);
  for (const char* method : {"bonferroni", "bh"}) {
    std::vector<double> adj = adjust_p_values(p, method);
    ASSERT_EQ(adj.size(), p.size());
    for (size_t i = 0; i < p.size(); ++i) {
      expect_rel(adj[i], want[method]["adj"][i].get<double>(), 1e-12,
                 std::string(method) + " #" + std::to_string(i));
      EXPECT_EQ(adj[i] <= alpha, want[method]["reject"][i].get<bool>()) << method << " #" << i;
    }
  }
  EXPECT_TRUE(adjust_p_values({}, "bh").empty());
  EXPECT_THROW(adjust_p_values(p, "holm"), ConfigError);

  // Through the CLI: p_adjusted is the BH adjustment of the printed p-values, selected <= alpha.
  json got = run_json({"granger", "--input", sh.one_csv, "--target", "y", "--correction", "bh",
                       "--alpha", "0.01", "--json"});
  std::vector<double> raw;
  for (const json& g : got) raw.push_back(g["p_value"].get<double>());
  std::vector<double> adj = adjust_p_values(raw, "bh");
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i]["p_adjusted"].get<double>(), adj[i]);
    EXPECT_EQ(got[i]["selected"].get<bool>(), adj[i] <= 0.01);
  }
}

TEST(GrangerFTest, RejectsBadInput) {
  Series y = {{1, 2, 3, 4, 5, 6, 7, 8}}, x = {{2, 1, 2, 1, 3, 1, 4, 1}};
  EXPECT_THROW(granger_f_test(y, x, 3), DataError);           // 5 rows, 7 regressors
  EXPECT_THROW(granger_f_test(y, {{1, 2, 3}}, 1), DataError);  // length mismatch
  EXPECT_THROW(granger_f_test(y, {{1, 2, 3, 4, 5, 6, 7, 8}, {1}}, 1), DataError);  // episodes
  EXPECT_THROW(granger_f_test(y, x, 0), DataError);
  Series with_nan = x;
  with_nan[0][2] = std::nan("");
  EXPECT_THROW(granger_f_test(y, with_nan, 1), DataError);
}

TEST(GrangerFTest, DegenerateCases) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<double> x(60), y(60), c(60, 2.5);
  for (double& v : x) v = noise(rng);
  for (int t = 0; t < 60; ++t) y[t] = t >= 1 ? x[t - 1] : 0.0;
  // y is exactly lagged x: the unrestricted fit is perfect, F infinite.
  GrangerTest perfect = granger_f_test({y}, {x}, 2);
  EXPECT_TRUE(std::isinf(perfect.f_stat));
  EXPECT_EQ(perfect.p_value, 0.0);
  // A constant target: nothing to explain, F = 0.
  GrangerTest flat = granger_f_test({c}, {x}, 2);
  EXPECT_EQ(flat.f_stat, 0.0);
  EXPECT_EQ(flat.p_value, 1.0);
  // A constant candidate (collinear with the intercept) adds nothing: F ~ 0, p ~ 1.
  GrangerTest none = granger_f_test({x}, {c}, 2);
  EXPECT_LT(none.f_stat, 1e-9);
  EXPECT_GT(none.p_value, 1 - 1e-9);
}

// `causaldrive granger ARGS` parsed and run inside this process (much faster than starting the
// binary, which loads libtorch); returns the message of the cd::Error of type E it throws.
template <class E>
std::string in_process_error(const std::vector<std::string>& args) {
  CLI::App app;
  cli::add_granger(app);
  std::vector<const char*> argv = {"causaldrive", "granger"};
  for (const std::string& a : args) argv.push_back(a.c_str());
  try {
    app.parse(static_cast<int>(argv.size()), argv.data());
  } catch (const E& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "unexpected exception: " << e.what();
    return "";
  }
  ADD_FAILURE() << "no error";
  return "";
}

struct BadInput {
  TempDir dir{"cd-granger"};
  std::string good = dir / "good.csv";
  BadInput() {
    std::string text = "episode,y,x\n";
    for (int i = 0; i < 30; ++i)
      text += std::string(i < 15 ? "a" : "b") + "," + std::to_string((i * 7) % 11) + "," +
              std::to_string((i * 5) % 13) + "\n";
    test::write_text(good, text);
  }
  std::string file_with(const std::string& name, const std::string& body) const {
    test::write_text(dir / name, body);
    return dir / name;
  }
  static std::vector<std::string> args(const std::string& file, std::vector<std::string> extra = {}) {
    std::vector<std::string> a = {"--input", file, "--target", "y", "--json"};
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  }
  static CommandResult cli(const std::string& file, std::vector<std::string> extra = {}) {
    std::vector<std::string> a = args(file, extra);
    a.insert(a.begin(), "granger");
    return test::run_cli(a);
  }
};

// Through the binary: one line on stderr naming the problem, exit code 1.
TEST(GrangerCli, BadInputIsOneLineError) {
  BadInput b;
  const std::vector<std::string> ep = {"--episode-col", "episode"};
  expect_one_line_error(b.cli(b.dir / "missing.csv"), "missing.csv: no such file");
  std::string line = expect_one_line_error(
      test::run_cli({"granger", "--input", b.good, "--target", "speed", "--episode-col", "episode"}),
      "no target column 'speed'");
  EXPECT_NE(line.find("(columns: y, x)"), std::string::npos) << line;
  expect_one_line_error(b.cli(b.file_with("text.csv", "y,x\n1,2\n3,abc\n")),
                        "text.csv:3, column 'x': 'abc' is not a finite number");
  expect_one_line_error(b.cli(b.file_with("again.csv", "episode,y,x\na,1,2\na,2,3\nb,3,1\na,4,4\n"), ep),
                        "again.csv:5: episode 'a' reappears");
  expect_one_line_error(b.cli(b.file_with("few.csv", "y,x\n1,2\n2,1\n3,3\n4,1\n5,2\n6,0\n")),
                        "too few rows");
  std::filesystem::create_directories(b.dir / "run");
  expect_one_line_error(test::run_cli({"granger", "--input", b.dir / "run"}), "without series.csv");
}

// The other checks, in process.
TEST(GrangerCli, RejectsBadArgumentsAndCells) {
  BadInput b;
  const std::vector<std::string> ep = {"--episode-col", "episode"};
  {
    CommandResult ok = b.cli(b.good, ep);  // the baseline these variations break
    ASSERT_TRUE(ok.exited && ok.exit_code == 0) << ok.describe();
  }
  auto has = [](const std::string& msg, const std::string& needle) {
    EXPECT_NE(msg.find(needle), std::string::npos) << "want '" << needle << "' in: " << msg;
  };
  has(in_process_error<ConfigError>(b.args(b.good, {"--episode-col", "ep"})),
      "no episode column 'ep' in " + b.good + " (columns: episode, y, x)");
  has(in_process_error<DataError>(b.args(b.good)), "good.csv:2, column 'episode': 'a' is not");
  has(in_process_error<DataError>(b.args(b.file_with("nan.csv", "y,x\n1,2\nnan,1\n"))),
      "nan.csv:3, column 'y': 'nan' is not a finite number");
  has(in_process_error<DataError>(b.args(b.file_with("inf.csv", "y,x\n1,2\n1,-inf\n"))),
      "inf.csv:3, column 'x': '-inf' is not a finite number");
  has(in_process_error<DataError>(b.args(b.file_with("empty.csv", "y,x\n1,2\n3,\n"))),
      "empty.csv:3, column 'x': empty cell");
  has(in_process_error<DataError>(b.args(b.file_with("cells.csv", "y,x\n1,2\n3\n"))),
      "cells.csv:3: 1 cells, the header has 2");
  has(in_process_error<DataError>(b.args(b.file_with("dup.csv", "y,x,y\n1,2,3\n"))),
      "column 'y' appears twice");
  has(in_process_error<DataError>(b.args(b.file_with("head.csv", "y,x\n"))), "no data rows");
  has(in_process_error<ConfigError>(b.args(b.good, {"--episode-col", "episode", "--correction", "holm"})),
      "unknown multiple-testing correction 'holm' (available: none, bonferroni, bh)");
  has(in_process_error<ConfigError>(b.args(b.good, {"--lags", "0"})), "--lags must be at least 1");
  has(in_process_error<ConfigError>(b.args(b.good, {"--alpha", "0"})), "--alpha must be in (0, 1]");
  has(in_process_error<ConfigError>(b.args(b.good, {"--episode-col", "episode", "--variables", "x,z"})),
      "no column 'z'");
  has(in_process_error<ConfigError>(b.args(b.good, {"--episode-col", "episode", "--variables", "y"})),
      "--variables names the target 'y'");
  has(in_process_error<ConfigError>({"--input", b.good}), "--target is required");
  has(in_process_error<IoError>({"--input", b.dir / "nope"}), "no such file");
}

}  // namespace
}  // namespace cd
