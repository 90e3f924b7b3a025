#include "core/progress.hpp"

#include "core/mpi.hpp"

#include <unistd.h>

#include <cstdio>

namespace cd {

std::string format_duration(double seconds) {
  long s = seconds < 0 ? 0 : static_cast<long>(seconds + 0.5);
  char buf[32];
  if (s >= 3600)
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
  else
    std::snprintf(buf, sizeof buf, "%ld:%02ld", s / 60, s % 60);
  return buf;
}

Progress::Progress(std::string label, long total, long already_done)
    : label_(std::move(label)),
      total_(total),
      done_(already_done),
      start_done_(already_done),
      tty_(isatty(STDERR_FILENO) != 0),
      start_(std::chrono::steady_clock::now()),
      last_print_(start_) {
  print(false, "");
}

void Progress::advance(long n, const std::string& note) {
  done_ += n;
  auto now = std::chrono::steady_clock::now();
  double since = std::chrono::duration<double>(now - last_print_).count();
  if (tty_ || since >= 5.0 || done_ == total_) print(false, note);
}

void Progress::finish(const std::string& note) { print(true, note); }

void Progress::print(bool final_line, const std::string& note) {
  auto now = std::chrono::steady_clock::now();
  last_print_ = now;
  double elapsed = std::chrono::duration<double>(now - start_).count();
  long fresh = done_ - start_done_;
  double rate = elapsed > 0 ? fresh / elapsed : 0.0;
  std::string eta = rate > 0 ? format_duration((total_ - done_) / rate) : "?";
  char line[512];
  std::snprintf(line, sizeof line, "[%s] %ld/%ld  %.2f/s  elapsed %s  ETA %s%s%s", label_.c_str(),
                done_, total_, rate, format_duration(elapsed).c_str(),
                final_line ? "0:00" : eta.c_str(), note.empty() ? "" : "  ", note.c_str());
  if (tty_) {
    std::fprintf(stderr, "\r\033[K%s%s", line, final_line ? "\n" : "");
  } else {
    std::fprintf(stderr, "%s\n", line);
  }
  std::fflush(stderr);
}

void log_line(const std::string& line) {
  std::fprintf(stderr, "%s%s\n", isatty(STDERR_FILENO) ? "\r\033[K" : "", line.c_str());
  std::fflush(stderr);
}

std::unique_ptr<Progress> job_progress(bool quiet, const std::string& label, long total,
                                       long todo) {
  if (quiet || !mpi_lead()) return nullptr;
  if (!mpi_distributed()) return std::make_unique<Progress>(label, total, total - todo);
  const long ranks = mpi_place().size, share = (todo + ranks - 1) / ranks;
  return std::make_unique<Progress>(label + ", rank 0 of " + std::to_string(ranks), share, 0);
}

}  // namespace cd
