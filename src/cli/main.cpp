// causaldrive: causal imitation learning for urban driving, one binary with subcommands.
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <memory>
#include <string>

#include <CLI/CLI.hpp>

#include "app/build_info.hpp"
#include "cli/commands.hpp"
#include "core/error.hpp"
#include "core/mpi.hpp"
#include "device/cpu_memory.hpp"

namespace {

// CLI11's message for a bad command line, on one line. Its range checks of unbounded numbers
// print the largest double in full; they say what they mean instead.
std::string usage_error(std::string msg) {
  const std::string range = " not in range ", huge = " to 1797693134862315";
  const size_t at = msg.find(range), top = msg.find(huge);
  if (at != std::string::npos && top != std::string::npos && top > at) {
    const std::string low = msg.substr(at + range.size(), top - at - range.size());
    msg = msg.substr(0, at) + (std::strtod(low.c_str(), nullptr) == 0 ? " is not a non-negative number"
                                                   : " is not a positive number");
  }
  for (char& c : msg)
    if (c == '\n') c = ' ';
  return msg;
}

// The subcommand a command line names (its first word that is not an option), or "".
std::string subcommand_of(int argc, char** argv) {
  for (int i = 1; i < argc; ++i)
    if (argv[i][0] != '-') return argv[i];
  return "";
}

// One line for an error. Under MPI it names the rank, and is printed (and flushed) before any
// abort: an error every rank knows (throw_job_error, the lead's lock or claim) ends each rank on
// its own, rank 0 printing it and the others nothing; an error this rank met alone ends every
// rank with MPI_Abort (the others may be waiting for this one in a collective), after its line.
int fail(const char* kind, const std::exception& e, int code) {
  if (dynamic_cast<const cd::MpiEchoError*>(&e) != nullptr) return code;
  if (cd::mpi_distributed())
    std::fprintf(stderr, "causaldrive: %s: %s: %s\n", kind, cd::mpi_where().c_str(), e.what());
  else
    std::fprintf(stderr, "causaldrive: %s: %s\n", kind, e.what());
  std::fflush(stderr);
  if (!cd::mpi_error_shared()) cd::mpi_abort(code);
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  // Large CPU tensors on huge pages (device/cpu_memory.hpp): the same numbers, fewer page faults.
  cd::use_huge_pages_for_cpu_tensors();
  // Under mpirun: MPI for the life of the command (core/mpi.hpp). Only collect and eval are
  // spread over ranks; the other ranks' stdout is dropped (rank 0 prints the results).
  std::unique_ptr<cd::MpiSession> mpi;
  try {
    mpi = std::make_unique<cd::MpiSession>(&argc, &argv);
    if (cd::mpi_distributed()) {
      const std::string sub = subcommand_of(argc, argv);
      if (!sub.empty() && sub != "collect" && sub != "eval")
        cd::throw_job_error("'" + sub + "' runs in one process; only collect and eval spread "
                            "over MPI ranks (start it without mpirun)");
      if (!cd::mpi_lead() && std::freopen("/dev/null", "w", stdout) == nullptr)
        throw cd::IoError("cannot silence the output of " + cd::mpi_where());
    }
  } catch (const cd::Error& e) {
    return fail("error", e, 1);
  }
  CLI::App app{
      "causaldrive: collect expert driving in SUMO, train imitation policies, measure inertia "
      "and collisions"};
  app.require_subcommand(1);
  app.set_version_flag("--version", cd::build_description());
  cd::cli::add_quickstart(app);
  cd::cli::add_town(app);
  cd::cli::add_collect(app);
  cd::cli::add_train(app);
  cd::cli::add_train_expert(app);
  cd::cli::add_eval(app);
  cd::cli::add_suite(app);
  cd::cli::add_probe(app);
  cd::cli::add_diagnose(app);
  cd::cli::add_attention(app);
  cd::cli::add_granger(app);
  cd::cli::add_report(app);
  cd::cli::add_bench(app);
  cd::cli::add_config(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // A bad command line: one line naming the problem, exit status 2 (usage).
    // (Under mpirun every rank sees the same command line: rank 0 says it.)
    if (cd::mpi_lead())
      std::fprintf(stderr, "causaldrive: error: %s (see --help)\n", usage_error(e.what()).c_str());
    return 2;
  } catch (const cd::Error& e) {
    return fail("error", e, 1);
  } catch (const std::exception& e) {
    return fail("internal error", e, 70);
  }
  return 0;
}
