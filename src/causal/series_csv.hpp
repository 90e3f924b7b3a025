#pragma once
// Reading variable time series for the Granger tests from a CSV file with a header row.
#include <string>
#include <vector>

namespace cd {

struct SeriesTable {
  std::string source;                    // the file, for messages
  std::vector<std::string> columns;      // the numeric columns, in file order (episode column left out)
  std::vector<std::string> episode_ids;  // one per episode; {""} when the file is one episode
  // values[c][e]: column c's values in episode e (all columns share the episode lengths).
  std::vector<std::vector<std::vector<double>>> values;
  long rows = 0;                         // data rows read

  bool has(const std::string& column) const;
  // The per-episode series of a column; ConfigError listing the columns when it is unknown.
  const std::vector<std::vector<double>>& column(const std::string& name) const;
};

// Reads `path`: a header row of distinct column names, then rows of comma-separated cells
// (double-quoted cells allowed; blank lines skipped). Every cell but those of `episode_col` must be
// a finite number; an episode is a maximal run of consecutive rows with the same episode value
// (any string), and a value that reappears after another one is an error. Empty `episode_col`:
// the whole file is one episode. Throws IoError (unreadable file), ConfigError (unknown episode
// column, listing the columns), DataError (malformed content, naming file, line and column).
SeriesTable read_series_csv(const std::string& path, const std::string& episode_col = "");

}  // namespace cd
