#pragma once
// Progress of long work: items, rate and ETA. On a terminal one line is redrawn in place;
// otherwise (logs, CI) a plain line is printed every few seconds.
#include <chrono>
#include <memory>
#include <string>

namespace cd {

class Progress {
 public:
  Progress(std::string label, long total, long already_done = 0);
  void advance(long n = 1, const std::string& note = "");
  void finish(const std::string& note = "");

 private:
  void print(bool final_line, const std::string& note);
  std::string label_;
  long total_, done_, start_done_;
  bool tty_;
  std::chrono::steady_clock::time_point start_, last_print_;
};

// The progress of a job of `total` items of which `todo` are left, or null when quiet. Under
// MPI (core/mpi.hpp) rank 0 shows its own share ("LABEL, rank 0 of N") and the others none.
std::unique_ptr<Progress> job_progress(bool quiet, const std::string& label, long total,
                                       long todo);

std::string format_duration(double seconds);  // "1:05:03" or "4:07"

// One line on stderr, clearing a progress line being redrawn on a terminal first.
void log_line(const std::string& line);

}  // namespace cd
