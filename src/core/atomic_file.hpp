#pragma once
// Atomic writes: content goes to a temporary name in the same folder, then a rename gives it
// its final name, so an interrupted run never leaves a file that looks complete.
#include <string>

namespace cd {

// A unique temporary path beside `final_path` (same folder, so rename is atomic).
std::string temp_path_for(const std::string& final_path);

// fsyncs the file at `tmp` and renames it to `final_path`. Throws IoError.
void commit_temp_file(const std::string& tmp, const std::string& final_path);

// Writes `content` atomically to `path`. Throws IoError.
void write_file_atomic(const std::string& path, const std::string& content);

// Removes the temporary files of interrupted writes in `dir` (they never carry a final name).
// Under MPI rank 0 removes them and every rank waits until it has (a collective).
void remove_stale_temporaries(const std::string& dir);

// The whole content of a file. Throws IoError when it cannot be read.
std::string read_file_bytes(const std::string& path);

}  // namespace cd
