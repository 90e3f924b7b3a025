#include "learn/dim_trainer.hpp"

#include "core/error.hpp"

namespace cd {

TrainSummary train_dim(const Settings&, const TrainRequest&) {
  throw Error("train_dim: being implemented");
}

}  // namespace cd
