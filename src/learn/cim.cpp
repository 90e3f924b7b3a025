#include "learn/cim.hpp"

#include "core/error.hpp"

namespace cd {

TrainSummary train_cim(const Settings&, const TrainRequest&) {
  throw Error("train_cim: being implemented");
}

}  // namespace cd
