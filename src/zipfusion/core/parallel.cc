#include "zipfusion/core/parallel.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace zipfusion {
namespace {

// How long a thread that ran out of work spins (yielding to any other runnable thread) before it
// sleeps. A frame set makes dozens of parallel_for calls a few microseconds apart; a sleeping
// thread on this virtual machine took 100–150 µs to wake (an idle virtual CPU is halted), which
// each call paid once for the worker and again for the caller when its block ended first.
constexpr std::chrono::microseconds kSpinBeforeSleep{300};

// Spins until done() or kSpinBeforeSleep has passed; returns done().
template <typename Done>
bool spin_until(Done&& done) {
  const auto deadline = std::chrono::steady_clock::now() + kSpinBeforeSleep;
  while (!done()) {
    std::this_thread::yield();
    if (std::chrono::steady_clock::now() > deadline) return done();
  }
  return true;
}

// One parallel_for call: its blocks still running and the first exception.
struct Job {
  std::atomic<int> remaining = 0;  // written under the pool's mutex, read by spinners without it
  std::exception_ptr first_error;
  std::condition_variable done;
};

// A block of one parallel_for call: body(i) for i in [begin, end).
struct Task {
  Job* job;
  IndexFunctionRef body;
  int begin, end;
  void run() const {
    for (int i = begin; i < end; ++i) body(i);
  }
};

// Workers kept for the life of the process: a frame set makes dozens of parallel_for calls, and
// starting threads for each cost about a millisecond per frame. A caller runs one block itself
// and, while its other blocks are pending, runs those of them still queued, so a nested call
// never waits on a worker that waits on it. It never runs another caller's blocks: that would
// add their time to its own (the pipeline's decoding to a frame's reconstruction).
class ThreadPool {
 public:
  explicit ThreadPool(int workers) {
    // Room for more blocks than are ever pending at once (each call queues one per worker, and
    // calls nest a level or two), so that how they interleave never makes the queue grow.
    queue_.reserve(64 * static_cast<size_t>(workers + 1));
    for (int i = 0; i < workers; ++i) workers_.emplace_back([this](std::stop_token stop) { work(stop); });
  }

  ~ThreadPool() {
    {
      // Under the lock: a worker between checking its wait condition and sleeping would
      // otherwise miss both the stop and the notification, and the join would wait for ever.
      std::lock_guard lock(mutex_);
      for (auto& worker : workers_) worker.request_stop();
    }
    wake_.notify_all();
  }

  int workers() const { return static_cast<int>(workers_.size()); }

  // Runs body over [begin, end) in `blocks` contiguous blocks: the first here, the others queued.
  void run(int begin, int end, IndexFunctionRef body, int blocks) {
    Job job;
    job.remaining = blocks;
    const long long count = end - begin;
    auto block = [&](int k) {
      return Task{&job, body, begin + static_cast<int>(count * k / blocks), begin + static_cast<int>(count * (k + 1) / blocks)};
    };
    {
      std::lock_guard lock(mutex_);
      for (int k = 1; k < blocks; ++k) queue_.push_back(block(k));
      queued_ += blocks - 1;
    }
    wake_.notify_all();
    execute(block(0));
    std::unique_lock lock(mutex_);
    while (job.remaining > 0) {
      const auto own = std::find_if(queue_.begin(), queue_.end(), [&](const Task& task) { return task.job == &job; });
      if (own != queue_.end()) {
        const Task task = *own;
        queue_.erase(own);
        --queued_;
        lock.unlock();
        execute(task);
        lock.lock();
      } else {
        lock.unlock();
        const bool finished = spin_until([&] { return job.remaining.load(std::memory_order_acquire) == 0; });
        lock.lock();
        if (!finished) job.done.wait(lock, [&] { return job.remaining == 0; });
      }
    }
    if (job.first_error) std::rethrow_exception(job.first_error);
  }

 private:
  void execute(const Task& task) {
    std::exception_ptr error;
    try {
      task.run();
    } catch (...) {
      error = std::current_exception();
    }
    std::lock_guard lock(mutex_);
    if (error && !task.job->first_error) task.job->first_error = error;
    if (--task.job->remaining == 0) task.job->done.notify_all();
  }

  void work(std::stop_token stop) {
    std::unique_lock lock(mutex_);
    while (true) {
      if (queue_.empty() && !stop.stop_requested()) {
        lock.unlock();
        spin_until([&] { return queued_.load(std::memory_order_relaxed) > 0 || stop.stop_requested(); });
        lock.lock();
      }
      wake_.wait(lock, [&] { return stop.stop_requested() || !queue_.empty(); });
      if (stop.stop_requested()) return;
      const Task task = queue_.front();
      queue_.erase(queue_.begin());
      --queued_;
      lock.unlock();
      execute(task);
      lock.lock();
    }
  }

  std::mutex mutex_;
  std::condition_variable wake_;
  // Pending blocks, oldest first: a vector, whose capacity stays (a deque allocated a node every
  // dozen blocks); it holds a few blocks, so erasing at the front costs nothing that matters.
  std::vector<Task> queue_;
  std::atomic<int> queued_ = 0;  // queue_.size(), written under the mutex, read by spinners without it
  std::vector<std::jthread> workers_;  // last: stopped and joined before the rest is destroyed
};

ThreadPool& pool() {
  static ThreadPool instance(std::max(1, hardware_threads() - 1));
  return instance;
}

}  // namespace

int hardware_threads() { return std::max(1u, std::thread::hardware_concurrency()); }

void parallel_for(int begin, int end, IndexFunctionRef body, int num_threads) {
  const int count = end - begin;
  if (count <= 0) return;
  ThreadPool& workers = pool();
  const int threads = std::min({count, num_threads > 0 ? num_threads : hardware_threads(), workers.workers() + 1});
  if (threads == 1) {
    for (int i = begin; i < end; ++i) body(i);
    return;
  }
  workers.run(begin, end, body, threads);
}

}  // namespace zipfusion
