#pragma once
// Progress of long work: items, rate and ETA. On a terminal one line is redrawn in place;
// otherwise (logs, CI) a plain line is printed every few seconds.
#include <chrono>
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

std::string format_duration(double seconds);  // "1:05:03" or "4:07"

// One line on stderr, clearing a progress line being redrawn on a terminal first.
void log_line(const std::string& line);

}  // namespace cd
