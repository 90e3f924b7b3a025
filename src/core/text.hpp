#pragma once
// Small text helpers shared by the readers of text formats (CSV series, the default config's
// comments, report's Markdown).
#include <string>
#include <string_view>

namespace cd {

// `s` without leading and trailing spaces, tabs and carriage returns.
inline std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r'))
    s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

// printf's formatting into a string of any length (an SVG element with a long label).
std::string format(const char* fmt, ...) __attribute__((format(printf, 1, 2)));

}  // namespace cd
