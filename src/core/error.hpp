#pragma once
// One exception hierarchy: the CLI turns any cd::Error into one line and a non-zero exit.
#include <stdexcept>
#include <string>

namespace cd {

struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};
// Bad or missing configuration: names the file and key.
struct ConfigError : Error {
  using Error::Error;
};
// Files that cannot be read or written, or whose content is not what it should be.
struct IoError : Error {
  using Error::Error;
};
// The simulator refused something or failed.
struct SimError : Error {
  using Error::Error;
};
// A dataset file that is malformed or inconsistent.
struct DataError : Error {
  using Error::Error;
};

}  // namespace cd
