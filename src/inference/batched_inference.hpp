#pragma once
// Closed-loop inference for many worlds at once (issue 46). libsumo runs one simulation per
// process, so an evaluation's worlds are processes (core/worker_pool.hpp). With batched
// inference one more process, the inference process, holds the policy networks: each world
// process's PolicyRunner::run writes its observation into its own slot of a shared-memory
// block and waits; the inference process takes every observation waiting at that moment,
// runs them through the network as one batch, and answers each slot.
//
// Same bytes: the networks run on batch-invariant kernels (nn/kernels.hpp) both here and in a
// world that runs its network itself, so an action depends on its observation alone, never
// on which observations were batched with it, the number of worlds or MPI ranks. (On CUDA the
// kernels are the device's, whose sums may depend on the batch; not measured.)
//
// Failures: a world that dies mid-request leaves its slot; the next episode in that worker
// takes it over (sequence numbers drop the stale answer). An inference process that dies is
// seen by every waiting world at once (its lifeline pipe closes): their episodes fail with
// "the inference process stopped", and check() stops the job with one line.
#include <sys/types.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/job.hpp"
#include "inference/policy_runner.hpp"

namespace cd {

struct BatchStats {
  long batches = 0, rows = 0;  // forward passes served and observations in them
  double infer_s = 0;          // the inference process's time inside them
};

class BatchedInference {
 public:
  // In a job's parent, before its workers fork: `worlds` slots, each for an observation of
  // up to `frame_bytes` bytes of frames (the whole history). Starts the inference process
  // (torch with `threads` intra-op threads); it loads each checkpoint at its first request.
  // `marker_dir`: the crash injection's (core/fault.hpp, site inference:<n>: the inference
  // process dies as it starts its n-th batch).
  BatchedInference(int worlds, size_t frame_bytes, const std::string& marker_dir = "",
                   int threads = 1);
  ~BatchedInference();  // stops the inference process
  BatchedInference(const BatchedInference&) = delete;
  BatchedInference& operator=(const BatchedInference&) = delete;

  // In a world process (a worker, before its first episode; the episodes' forks inherit it):
  // this process's PolicyRunners send their observations through slot `slot`.
  void connect(int slot);
  // In the parent, after an attempt of the workers: throws JobError ("the inference process
  // (pid N) stopped: ...; rerun the same command to resume") when the inference process died.
  void check();
  BatchStats stats() const;
  pid_t pid() const { return server_; }

 struct Block;  // the shared memory's header (its slots follow it)

 private:
  void release();  // stops the inference process, frees the memory and the events
  Block* block_ = nullptr;
  size_t bytes_ = 0;        // of the mapping
  size_t frame_bytes_ = 0;  // a slot's room for frames
  int worlds_ = 0;
  pid_t server_ = -1;
  int requests_fd_ = -1, lifeline_fd_ = -1;
  std::vector<int> answer_fds_;
  std::string died_;  // why the inference process stopped, once seen
};

// An evaluation job's inference, driving and MuJoCo-Image alike: for a policy-family agent
// (`input`: its checkpoint's input format; null for any other agent), with eval.batch `batch`
// "on", or "auto" and `device` (eval.device resolved) cuda, and spec.workers >= 2, outside MPI
// and in-process jobs, starts the inference process and wires the job to it: each worker
// connects after its own spec.setup, and a dead inference process stops the job after the
// attempt. Call it once spec.out, workers, in_process and setup are set. Returns the inference
// process's handle, or null where the worlds run their networks.
std::unique_ptr<BatchedInference> start_job_inference(JobSpec& spec, const std::string& batch,
                                                      const std::string& device,
                                                      const InputFormat* input);
// What run.json records under "inference": "batch-1" (the bytes of one observation at a time:
// every CPU evaluation, served or not, and every earlier folder) or "batched-cuda" (served on
// the GPU, whose kernels may sum a row differently by batch; not measured).
std::string inference_record(const BatchedInference* served, const std::string& device);

// PolicyRunner::run's way to the inference process: true when this process is connected and
// the observation fits, `step` and `action` then hold the answer. Throws Error when the
// inference process stopped or failed on this observation.
bool remote_policy_run(const std::string& key, const uint8_t* const* frames, int history,
                       size_t frame_values, double speed, int command, const float* previous,
                       int previous_values, PolicyStep* step, std::vector<float>* action);

}  // namespace cd
