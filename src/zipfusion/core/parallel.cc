#include "zipfusion/core/parallel.h"

#include <algorithm>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace zipfusion {

int hardware_threads() { return std::max(1u, std::thread::hardware_concurrency()); }

void parallel_for(int begin, int end, const std::function<void(int)>& body, int num_threads) {
  const int count = end - begin;
  if (count <= 0) return;
  const int threads = std::min(count, num_threads > 0 ? num_threads : hardware_threads());
  if (threads == 1) {
    for (int i = begin; i < end; ++i) body(i);
    return;
  }
  std::exception_ptr first_error;
  std::mutex error_mutex;
  auto run_block = [&](int block) {
    const int lo = begin + static_cast<int>(static_cast<long long>(count) * block / threads);
    const int hi = begin + static_cast<int>(static_cast<long long>(count) * (block + 1) / threads);
    try {
      for (int i = lo; i < hi; ++i) body(i);
    } catch (...) {
      std::lock_guard lock(error_mutex);
      if (!first_error) first_error = std::current_exception();
    }
  };
  std::vector<std::jthread> workers;
  workers.reserve(threads - 1);
  for (int block = 1; block < threads; ++block) workers.emplace_back(run_block, block);
  run_block(0);
  workers.clear();  // joins
  if (first_error) std::rethrow_exception(first_error);
}

}  // namespace zipfusion
