#include "causal/granger.hpp"

#include "core/error.hpp"

namespace cd {

GrangerTest granger_f_test(const std::vector<std::vector<double>>&,
                           const std::vector<std::vector<double>>&, int,
                           const std::vector<std::vector<std::vector<double>>>&) {
  throw Error("granger_f_test: being implemented");
}

std::vector<double> adjust_p_values(const std::vector<double>&, const std::string&) {
  throw Error("adjust_p_values: being implemented");
}

}  // namespace cd
