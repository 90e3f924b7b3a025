#include "world/sumo_errors.hpp"

#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <sstream>

#include "core/error.hpp"

namespace cd {

namespace {

// Redirects fd 2 into an unnamed temporary file for its lifetime.
class StderrCapture {
 public:
  StderrCapture() {
    std::fflush(stderr);
    file_ = std::tmpfile();
    saved_ = dup(STDERR_FILENO);
    if (file_ && saved_ >= 0) dup2(fileno(file_), STDERR_FILENO);
  }
  ~StderrCapture() {
    restore();
    if (file_) std::fclose(file_);
  }
  void restore() {
    if (saved_ >= 0) {
      std::fflush(stderr);
      dup2(saved_, STDERR_FILENO);
      close(saved_);
      saved_ = -1;
    }
  }
  std::string first_error() {
    restore();
    if (!file_) return "";
    std::rewind(file_);
    std::string text, line, first;
    char buf[4096];
    size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, file_)) > 0) text.append(buf, n);
    std::istringstream in(text);
    std::string detail;
    while (std::getline(in, line)) {
      if (line.rfind("Error: ", 0) == 0 && first.empty()) {
        first = line.substr(7);
      } else if (!first.empty() && line.rfind(" ", 0) == 0) {
        detail += line;  // SUMO indents the file and position under the message
      } else if (!first.empty()) {
        break;
      }
    }
    return first + detail;
  }

 private:
  std::FILE* file_ = nullptr;
  int saved_ = -1;
};

}  // namespace

void throw_sim_error(const std::string& context, const std::exception& e) {
  if (dynamic_cast<const SimError*>(&e)) throw SimError(e.what());
  throw SimError(context + ": " + e.what());
}

void with_sumo_errors(const std::string& context, const std::function<void()>& fn) {
  StderrCapture capture;
  try {
    fn();
  } catch (const std::exception& e) {
    std::string why = capture.first_error();
    if (why.empty()) why = e.what();
    throw SimError(context + ": " + why);
  }
}

}  // namespace cd
