#pragma once
// What a MuJoCo-Image worker process (collect --env, eval --env) reports to its parent for one
// finished episode: its steps and return, as the pool's one-line note, and the progress line
// the parent prints from it.
#include <cstdio>
#include <sstream>
#include <string>

namespace cd::mj {

struct EpisodeNote {
  long steps = 0;
  double ret = 0;

  std::string encode() const {
    char b[64];
    std::snprintf(b, sizeof b, "%ld %.3f", steps, ret);
    return b;
  }
  static EpisodeNote decode(const std::string& note) {
    EpisodeNote n;
    std::istringstream in(note);
    in >> n.steps >> n.ret;
    return n;
  }
  std::string progress_line(int index) const {
    char b[96];
    std::snprintf(b, sizeof b, "episode %d: %ld steps, return %.1f", index, steps, ret);
    return b;
  }
};

}  // namespace cd::mj
