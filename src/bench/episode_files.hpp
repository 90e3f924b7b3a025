#pragma once
// The files of episode i in an eval folder's episodes/, both domains: its record (the commit of
// the episode) and, with --record, its recording in the domain's HDF5 layout.
#include <cstdio>
#include <string>

namespace cd {

inline std::string episode_record_name(int index) {  // episode_000012.json
  char name[40];
  std::snprintf(name, sizeof name, "episode_%06d.json", index);
  return name;
}

inline std::string episode_recording_name(int index) {  // episode_000012.h5
  char name[40];
  std::snprintf(name, sizeof name, "episode_%06d.h5", index);
  return name;
}

}  // namespace cd
