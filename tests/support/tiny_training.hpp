#pragma once
// In-process training of a family method on a hand-made data folder (dir/data), small and
// fast: narrow network, 1 torch thread, 1 epoch, a third of the episodes held out.
#include <string>

#include "methods/method.hpp"
#include "test_support.hpp"
#include "train/request.hpp"

namespace cd::test {

inline Settings tiny_family_settings() {
  Settings s;
  s.model.features = 16;
  s.model.history = 3;
  s.model.history_stride = 2;
  s.model.dropout = 0;
  s.train.batch_size = 16;
  s.train.threads = 1;
  s.train.device = "cpu";  // same bytes are the CPU's (a GPU machine would resolve auto to CUDA)
  s.train.lr = 1e-3;
  s.train.epochs = 1;
  s.train.val_fraction = 0.34;
  return s;
}

// Trains `method` on dir/DATA (default "data") into dir/name; returns the run folder.
inline std::string train_tiny_run(const TempDir& dir, const std::string& method,
                                  const std::string& name,
                                  const Settings& s = tiny_family_settings(),
                                  const std::string& data = "data") {
  TrainRequest req;
  req.method = method;
  req.data_dir = dir / data;
  req.out_dir = dir / name;
  req.quiet = true;
  train_method(s, req);
  return req.out_dir;
}

}  // namespace cd::test
