#include "causal/series_csv.hpp"

#include <charconv>
#include <cmath>
#include <fstream>
#include <set>
#include <string_view>

#include "core/error.hpp"
#include "core/text.hpp"

namespace cd {

namespace {

std::string join(const std::vector<std::string>& names) {
  std::string s;
  for (const std::string& n : names) s += (s.empty() ? "" : ", ") + n;
  return s;
}

// Splits one CSV line into trimmed cells. A cell may be double-quoted ("" is a quote inside);
// quoted content is kept verbatim. `where` prefixes error messages ("FILE:LINE").
std::vector<std::string> split_cells(std::string_view line, const std::string& where) {
  std::vector<std::string> cells;
  size_t i = 0;
  while (true) {
    // Skip leading blanks of the cell.
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    std::string cell;
    if (i < line.size() && line[i] == '"') {
      ++i;
      bool closed = false;
      while (i < line.size()) {
        if (line[i] == '"') {
          if (i + 1 < line.size() && line[i + 1] == '"') {
            cell += '"';
            i += 2;
            continue;
          }
          closed = true;
          ++i;
          break;
        }
        cell += line[i++];
      }
      if (!closed) throw DataError(where + ": unterminated double quote");
      size_t comma = line.find(',', i);
      if (!trim(line.substr(i, comma == std::string_view::npos ? line.npos : comma - i)).empty())
        throw DataError(where + ": text after a closing double quote");
      i = comma;
    } else {
      size_t comma = line.find(',', i);
      cell = std::string(trim(line.substr(i, comma == std::string_view::npos ? line.npos : comma - i)));
      i = comma;
    }
    cells.push_back(std::move(cell));
    if (i == std::string_view::npos) break;
    ++i;  // past the comma
  }
  return cells;
}

// A finite number, or nothing (empty, text, out of range, nan, inf).
bool parse_number(std::string_view s, double& v) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return ec == std::errc() && ptr == s.data() + s.size() && std::isfinite(v);
}

}  // namespace

bool SeriesTable::has(const std::string& name) const {
  for (const std::string& c : columns)
    if (c == name) return true;
  return false;
}

const std::vector<std::vector<double>>& SeriesTable::column(const std::string& name) const {
  for (size_t c = 0; c < columns.size(); ++c)
    if (columns[c] == name) return values[c];
  throw ConfigError("no column '" + name + "' in " + source + " (columns: " + join(columns) + ")");
}

SeriesTable read_series_csv(const std::string& path, const std::string& episode_col) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("cannot read " + path + " (missing or not readable)");
  SeriesTable t;
  t.source = path;

  std::string line;
  long line_no = 0;
  std::vector<std::string> header;
  while (std::getline(in, line)) {
    ++line_no;
    if (line_no == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);  // UTF-8 BOM
    if (trim(line).empty()) continue;
    header = split_cells(line, path + ":" + std::to_string(line_no));
    break;
  }
  if (header.empty()) throw DataError(path + ": empty file (expected a header row)");
  std::set<std::string> seen_names;
  for (size_t c = 0; c < header.size(); ++c) {
    if (header[c].empty())
      throw DataError(path + ":" + std::to_string(line_no) + ": column " + std::to_string(c + 1) +
                      " of the header has no name");
    if (!seen_names.insert(header[c]).second)
      throw DataError(path + ":" + std::to_string(line_no) + ": column '" + header[c] +
                      "' appears twice in the header");
  }
  int ep_index = -1;
  if (!episode_col.empty()) {
    for (size_t c = 0; c < header.size(); ++c)
      if (header[c] == episode_col) ep_index = static_cast<int>(c);
    if (ep_index < 0)
      throw ConfigError("no episode column '" + episode_col + "' in " + path +
                        " (columns: " + join(header) + ")");
  }
  std::vector<int> slot(header.size(), -1);  // header index -> values index
  for (size_t c = 0; c < header.size(); ++c) {
    if (static_cast<int>(c) == ep_index) continue;
    slot[c] = static_cast<int>(t.columns.size());
    t.columns.push_back(header[c]);
  }
  t.values.resize(t.columns.size());

  std::set<std::string> finished;  // episodes that ended (a later row with one is an error)
  bool any_row = false;
  std::string current;
  while (std::getline(in, line)) {
    ++line_no;
    if (trim(line).empty()) continue;
    const std::string where = path + ":" + std::to_string(line_no);
    std::vector<std::string> cells = split_cells(line, where);
    if (cells.size() != header.size())
      throw DataError(where + ": " + std::to_string(cells.size()) + " cells, the header has " +
                      std::to_string(header.size()));
    const std::string ep = ep_index >= 0 ? cells[ep_index] : std::string();
    if (!any_row || ep != current) {
      if (any_row) finished.insert(current);
      if (finished.count(ep))
        throw DataError(where + ": episode '" + ep + "' reappears after other episodes (the rows "
                        "of an episode must be consecutive)");
      current = ep;
      t.episode_ids.push_back(ep);
      for (auto& v : t.values) v.emplace_back();
      any_row = true;
    }
    for (size_t c = 0; c < cells.size(); ++c) {
      if (slot[c] < 0) continue;
      double v = 0;
      if (!parse_number(cells[c], v))
        throw DataError(where + ", column '" + header[c] + "': " +
                        (cells[c].empty() ? std::string("empty cell")
                                          : "'" + cells[c] + "' is not a finite number"));
      t.values[slot[c]].back().push_back(v);
    }
    ++t.rows;
  }
  if (in.bad()) throw IoError("error reading " + path);
  if (!any_row) throw DataError(path + ": no data rows after the header");
  return t;
}

}  // namespace cd
