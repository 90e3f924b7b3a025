#pragma once
// Validated TOML configuration. Every lookup names its key; keys that nobody asked for are
// reported as unknown by Section::finish(), so a typo never passes silently.
#include <cstdint>
#include <memory>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace cd {

class Section {
 public:
  double number(std::string_view key, double fallback, double lo, double hi) const;
  int64_t integer(std::string_view key, int64_t fallback, int64_t lo, int64_t hi) const;
  bool boolean(std::string_view key, bool fallback) const;
  std::string string(std::string_view key, const std::string& fallback,
                     const std::vector<std::string>& allowed = {}) const;
  std::vector<std::string> strings(std::string_view key,
                                   const std::vector<std::string>& fallback) const;
  bool has(std::string_view key) const;
  // A sub-table; an absent one is an empty section (all defaults).
  Section section(std::string_view key) const;
  // Throws ConfigError naming the first key of this section that was never looked up.
  void finish() const;

  const std::string& file() const;
  std::string key_path(std::string_view key) const;  // "world.town"

  struct Impl;  // defined in config.cpp

 private:
  friend class ConfigFile;
  std::shared_ptr<Impl> impl_;
};

class ConfigFile {
 public:
  // Throws ConfigError: missing file, or TOML syntax error with line and column.
  static Section load(const std::string& path);
  static Section parse(const std::string& text, const std::string& name);
};

}  // namespace cd
