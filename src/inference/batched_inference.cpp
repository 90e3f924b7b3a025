#include "inference/batched_inference.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstring>
#include <map>
#include <memory>
#include <chrono>
#include <thread>

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/mpi.hpp"

namespace cd {

namespace {

enum : uint64_t { kIdle = 0, kRequest = 1, kAnswer = 2, kFailed = 3 };
constexpr size_t kKeyBytes = 1024, kMaxPrevious = 16, kMaxAction = 32, kErrorBytes = 480;

uint64_t word_of(uint64_t seq, uint64_t state) { return seq << 2 | state; }

// One world's request and its answer. The word (sequence number, state) is the only field
// both sides write: the client its requests, the inference process its answers by
// compare-and-swap from exactly the request it read, so an answer to a request that a dead
// world left behind never lands on the next world's request.
struct Slot {
  std::atomic<uint64_t> word;
  uint32_t key_len;
  char key[kKeyBytes];
  double speed;
  int32_t command, history;
  uint64_t frame_values;
  int32_t previous_values;
  float previous[kMaxPrevious];
  double throttle, brake, steer, target_speed;
  int32_t action_n;
  float action[kMaxAction];
  uint32_t error_len;
  char error[kErrorBytes];
};

struct Header {
  std::atomic<int> shutdown;
  std::atomic<long> batches, rows;
  std::atomic<long> infer_ns;  // inside the forward passes
};

size_t round_up(size_t n) { return (n + 63) / 64 * 64; }

struct Client {
  Slot* slot = nullptr;
  uint8_t* frames = nullptr;
  size_t capacity = 0;
  int requests_fd = -1, answer_fd = -1, lifeline_fd = -1;
};
Client client;  // this process's connection (a world process), if any

void post(int fd) {
  const uint64_t one = 1;
  ssize_t ignored = write(fd, &one, sizeof one);
  (void)ignored;
}

}  // namespace

struct BatchedInference::Block {
  Header header;
};

namespace {

size_t slot_stride(size_t frame_bytes) { return round_up(sizeof(Slot)) + round_up(frame_bytes); }
Slot* slot_at(BatchedInference::Block* b, size_t stride, int i) {
  return reinterpret_cast<Slot*>(reinterpret_cast<char*>(b) + round_up(sizeof(Header)) +
                                 stride * static_cast<size_t>(i));
}
uint8_t* frames_of(Slot* s) { return reinterpret_cast<uint8_t*>(s) + round_up(sizeof(Slot)); }

void set_error(Slot* s, const std::string& what) {
  const size_t n = std::min(what.size(), kErrorBytes);
  std::memcpy(s->error, what.data(), n);
  s->error_len = static_cast<uint32_t>(n);
}

// The inference process: waits for requests, answers every waiting one in one batch per
// checkpoint, until the parent says stop.
[[noreturn]] void serve(BatchedInference::Block* block, size_t stride, int worlds,
                        int requests_fd, const std::vector<int>& answer_fds,
                        const std::string& marker_dir, int threads) {
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  set_torch_threads(threads);
  std::map<std::string, std::unique_ptr<PolicyRunner>> runners;
  struct Row {
    int slot;
    uint64_t seq;
  };
  using Clock = std::chrono::steady_clock;
  // When each world last asked: a world that asked within kActive is driving, and a batch
  // waits (at most kLinger) until every driving world has asked. A world between episodes
  // (reset, history prefill) stops counting after kActive.
  constexpr auto kActive = std::chrono::milliseconds(20);
  constexpr auto kLinger = std::chrono::microseconds(2000);
  std::vector<Clock::time_point> asked(static_cast<size_t>(worlds), Clock::time_point{});
  for (;;) {
    uint64_t count = 0;
    if (read(requests_fd, &count, sizeof count) < 0 && errno != EINTR) _exit(1);
    if (block->header.shutdown.load()) _exit(0);
    std::map<std::string, std::vector<Row>> waiting;  // by checkpoint
    const Clock::time_point woke = Clock::now();
    for (;;) {
      waiting.clear();
      int ready = 0, driving = 0;
      const Clock::time_point now = Clock::now();
      for (int i = 0; i < worlds; ++i) {
        Slot* s = slot_at(block, stride, i);
        const uint64_t w = s->word.load(std::memory_order_acquire);
        if ((w & 3) == kRequest) {
          asked[static_cast<size_t>(i)] = now;
          ++ready;
          waiting[std::string(s->key, std::min<size_t>(s->key_len, kKeyBytes))].push_back(
              {i, w >> 2});
        }
        driving += now - asked[static_cast<size_t>(i)] < kActive;
      }
      const auto left = kLinger - (now - woke);
      if (2 * ready >= driving || left <= Clock::duration::zero()) break;
      pollfd p = {requests_fd, POLLIN, 0};
      const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(left).count();
      const timespec wait = {static_cast<time_t>(ns / 1000000000), static_cast<long>(ns % 1000000000)};
      if (ppoll(&p, 1, &wait, nullptr) > 0 && (p.revents & POLLIN)) {
        ssize_t ignored = read(requests_fd, &count, sizeof count);
        (void)ignored;
      }
      if (block->header.shutdown.load()) _exit(0);
    }
    for (auto& [key, rows] : waiting) {
      inject_crash("inference", block->header.batches.load(), marker_dir);
      std::vector<std::vector<const uint8_t*>> frames(rows.size());
      std::vector<PolicyInput> inputs(rows.size());
      for (size_t r = 0; r < rows.size(); ++r) {
        Slot* s = slot_at(block, stride, rows[r].slot);
        for (int k = 0; k < s->history; ++k)
          frames[r].push_back(frames_of(s) + static_cast<size_t>(k) * s->frame_values);
        inputs[r] = PolicyInput{frames[r].data(), s->speed, s->command,
                                s->previous_values > 0 ? s->previous : nullptr};
      }
      std::vector<PolicyStep> steps;
      std::vector<std::vector<float>> actions;
      std::string failure;
      try {
        auto& runner = runners[key];
        if (!runner) {
          // key: dir, expected method, weights file, device (one per line)
          std::vector<std::string> f;
          size_t at = 0;
          for (size_t nl; (nl = key.find('\n', at)) != std::string::npos; at = nl + 1)
            f.push_back(key.substr(at, nl - at));
          f.push_back(key.substr(at));
          if (f.size() != 4) throw Error("malformed inference request");
          runner = std::make_unique<PolicyRunner>(f[0], f[1], f[2], f[3]);
        }
        const auto t0 = Clock::now();
        steps = runner->run_batch(inputs, &actions);
        block->header.infer_ns.fetch_add(
            std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - t0).count());
      } catch (const std::exception& e) {
        runners.erase(key);
        failure = std::string("the inference process: ") + e.what();
      }
      block->header.batches.fetch_add(1);
      block->header.rows.fetch_add(static_cast<long>(rows.size()));
      for (size_t r = 0; r < rows.size(); ++r) {
        Slot* s = slot_at(block, stride, rows[r].slot);
        uint64_t expected = word_of(rows[r].seq, kRequest);
        if (failure.empty()) {
          s->throttle = steps[r].throttle;
          s->brake = steps[r].brake;
          s->steer = steps[r].steer;
          s->target_speed = steps[r].target_speed;
          const size_t n = std::min(actions[r].size(), kMaxAction);
          std::copy_n(actions[r].data(), n, s->action);
          s->action_n = static_cast<int32_t>(n);
        } else {
          set_error(s, failure);
        }
        if (s->word.compare_exchange_strong(expected,
                                            word_of(rows[r].seq, failure.empty() ? kAnswer : kFailed),
                                            std::memory_order_acq_rel))
          post(answer_fds[static_cast<size_t>(rows[r].slot)]);
      }
    }
  }
}

std::string status_text(int status) {
  if (WIFSIGNALED(status)) return "killed by signal " + std::to_string(WTERMSIG(status));
  return "exited with status " + std::to_string(WEXITSTATUS(status));
}

}  // namespace

BatchedInference::BatchedInference(int worlds, size_t frame_bytes, const std::string& marker_dir,
                                   int threads)
    : frame_bytes_(frame_bytes), worlds_(std::max(1, worlds)) {
  const size_t stride = slot_stride(frame_bytes);
  bytes_ = round_up(sizeof(Header)) + stride * static_cast<size_t>(worlds_);
  void* p = mmap(nullptr, bytes_, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED)
    throw IoError("cannot map shared memory for batched inference: " +
                  std::string(std::strerror(errno)));
  block_ = static_cast<Block*>(p);
  new (&block_->header) Header();
  for (int i = 0; i < worlds_; ++i) {
    Slot* s = slot_at(block_, stride, i);
    new (&s->word) std::atomic<uint64_t>(kIdle);
  }
  requests_fd_ = eventfd(0, EFD_CLOEXEC);
  int lifeline[2] = {-1, -1};
  bool ok = requests_fd_ >= 0 && pipe2(lifeline, O_CLOEXEC) == 0;
  for (int i = 0; ok && i < worlds_; ++i) {
    answer_fds_.push_back(eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC));
    ok = answer_fds_.back() >= 0;
  }
  if (!ok) {
    const std::string why = std::strerror(errno);
    if (lifeline[1] >= 0) close(lifeline[1]);
    lifeline_fd_ = lifeline[0];
    release();
    throw IoError("cannot create the batched inference's events: " + why);
  }
  lifeline_fd_ = lifeline[0];
  std::fflush(nullptr);
  server_ = fork();
  if (server_ < 0) {
    const std::string why = std::strerror(errno);
    close(lifeline[1]);
    release();
    throw Error("cannot start the inference process: " + why);
  }
  if (server_ == 0) {
    close(lifeline[0]);  // the write end stays open while this process lives
    serve(block_, stride, worlds_, requests_fd_, answer_fds_, marker_dir, threads);
  }
  close(lifeline[1]);
}

BatchedInference::~BatchedInference() { release(); }

void BatchedInference::release() {
  if (server_ > 0) {
    block_->header.shutdown.store(1);
    post(requests_fd_);
    int status = 0;
    pid_t r = 0;
    for (int i = 0; i < 200 && (r = waitpid(server_, &status, WNOHANG)) == 0; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (r == 0) {
      kill(server_, SIGKILL);
      waitpid(server_, &status, 0);
    }
    server_ = -1;
  }
  for (int fd : answer_fds_)
    if (fd >= 0) close(fd);
  answer_fds_.clear();
  if (requests_fd_ >= 0) close(requests_fd_);
  if (lifeline_fd_ >= 0) close(lifeline_fd_);
  requests_fd_ = lifeline_fd_ = -1;
  if (block_) munmap(block_, bytes_);
  block_ = nullptr;
}

void BatchedInference::connect(int slot) {
  if (slot < 0 || slot >= worlds_)
    throw Error("batched inference: no slot " + std::to_string(slot) + " (" +
                std::to_string(worlds_) + " worlds)");
  Slot* s = slot_at(block_, slot_stride(frame_bytes_), slot);
  client = Client{s, frames_of(s), frame_bytes_, requests_fd_,
                  answer_fds_[static_cast<size_t>(slot)], lifeline_fd_};
}

void BatchedInference::check() {
  if (server_ <= 0) return;
  if (died_.empty()) {
    int status = 0;
    if (waitpid(server_, &status, WNOHANG) == server_) {
      died_ = status_text(status);
      const pid_t pid = server_;
      server_ = -1;
      throw_job_error("the inference process (pid " + std::to_string(pid) + ") stopped: " +
                      died_ + "; rerun the same command to resume");
    }
  }
}

BatchStats BatchedInference::stats() const {
  return BatchStats{block_->header.batches.load(), block_->header.rows.load(),
                    block_->header.infer_ns.load() * 1e-9};
}

std::unique_ptr<BatchedInference> start_job_inference(JobSpec& spec, const std::string& batch,
                                                      const std::string& device,
                                                      const InputFormat* input) {
  const bool on = batch == "on" || (batch == "auto" && device == "cuda");
  if (!on || !input || spec.in_process || mpi_distributed() || spec.workers < 2) return nullptr;
  auto inference = std::make_unique<BatchedInference>(
      spec.workers,
      static_cast<size_t>(input->history) * input->channels * input->height * input->width,
      spec.out);
  BatchedInference* served = inference.get();
  std::function<void()> setup = spec.setup;
  spec.setup = [setup, served] {
    if (setup) setup();
    served->connect(worker_index());
  };
  spec.after_attempt = [served] { served->check(); };
  return inference;
}

std::string inference_record(const BatchedInference* served, const std::string& device) {
  return served && device == "cuda" ? "batched-cuda" : "batch-1";
}

bool remote_policy_run(const std::string& key, const uint8_t* const* frames, int history,
                       size_t frame_values, double speed, int command, const float* previous,
                       int previous_values, PolicyStep* step, std::vector<float>* action) {
  Client& c = client;
  if (!c.slot) return false;
  const size_t need = static_cast<size_t>(history) * frame_values;
  if (need > c.capacity || key.size() > kKeyBytes || previous_values > int(kMaxPrevious))
    return false;
  Slot* s = c.slot;
  const uint64_t seq = (s->word.load(std::memory_order_acquire) >> 2) + 1;
  std::memcpy(s->key, key.data(), key.size());
  s->key_len = static_cast<uint32_t>(key.size());
  for (int k = 0; k < history; ++k)
    std::memcpy(c.frames + static_cast<size_t>(k) * frame_values, frames[k], frame_values);
  s->history = history;
  s->frame_values = frame_values;
  s->speed = speed;
  s->command = command;
  s->previous_values = previous ? previous_values : 0;
  if (previous) std::copy_n(previous, previous_values, s->previous);
  s->word.store(word_of(seq, kRequest), std::memory_order_release);
  post(c.requests_fd);
  for (;;) {
    const uint64_t w = s->word.load(std::memory_order_acquire);
    if (w == word_of(seq, kAnswer)) {
      step->throttle = s->throttle;
      step->brake = s->brake;
      step->steer = s->steer;
      step->target_speed = s->target_speed;
      action->assign(s->action, s->action + s->action_n);
      return true;
    }
    if (w == word_of(seq, kFailed)) throw Error(std::string(s->error, s->error_len));
    pollfd fds[2] = {{c.answer_fd, POLLIN, 0}, {c.lifeline_fd, POLLIN, 0}};
    const int n = poll(fds, 2, 1000);
    if (n < 0 && errno != EINTR) throw Error("batched inference: poll failed");
    if (fds[0].revents & POLLIN) {
      uint64_t drained = 0;
      ssize_t ignored = read(c.answer_fd, &drained, sizeof drained);
      (void)ignored;
    }
    if (fds[1].revents && s->word.load(std::memory_order_acquire) != word_of(seq, kAnswer))
      throw Error("the inference process stopped");
  }
}

}  // namespace cd
