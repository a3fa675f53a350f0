// Host parallel_for: a persistent pool of worker threads that hands out
// chunks of an index range dynamically. Each call gets the worker's id so
// kernels can keep per-thread scratch (tapes, leaf logs). The device side
// of the same idea is cuda/launch.cuh.
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace difftrans {

class ThreadPool {
 public:
  // threads <= 0: DIFFTRANS_THREADS from the environment, else all cores.
  explicit ThreadPool(int threads = 0) {
    if (threads <= 0) {
      const char* env = std::getenv("DIFFTRANS_THREADS");
      threads = env ? std::atoi(env) : 0;
    }
    if (threads <= 0) threads = int(std::max(1u, std::thread::hardware_concurrency()));
    for (int w = 1; w < threads; ++w) workers_.emplace_back([this, w] { worker_loop(w); });
  }

  ~ThreadPool() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    for (auto& t : workers_) t.join();
  }

  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int size() const { return int(workers_.size()) + 1; }

  // Runs body(begin, end, worker) over [0, count) in chunks of `grain`; the
  // calling thread works too (as worker 0). Rethrows the first exception.
  void parallel_for(std::int64_t count, std::int64_t grain,
                    const std::function<void(std::int64_t, std::int64_t, int)>& body) {
    if (count <= 0) return;
    grain = std::max<std::int64_t>(1, grain);
    if (workers_.empty() || count <= grain) {
      body(0, count, 0);
      return;
    }
    std::unique_lock<std::mutex> run_lock(run_mutex_);  // one job at a time
    {
      std::lock_guard<std::mutex> lock(mutex_);
      job_ = &body;
      count_ = count;
      grain_ = grain;
      next_.store(0);
      error_ = nullptr;
      active_ = int(workers_.size());
      ++generation_;
    }
    wake_.notify_all();
    work(0);
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [this] { return active_ == 0; });
    job_ = nullptr;
    if (error_) std::rethrow_exception(error_);
  }

  // The process-wide pool.
  static ThreadPool& global() {
    static ThreadPool pool;
    return pool;
  }

 private:
  void work(int worker) {
    for (;;) {
      const std::int64_t begin = next_.fetch_add(grain_);
      if (begin >= count_) return;
      try {
        (*job_)(begin, std::min(count_, begin + grain_), worker);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!error_) error_ = std::current_exception();
        next_.store(count_);
      }
    }
  }

  void worker_loop(int worker) {
    std::uint64_t seen = 0;
    for (;;) {
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
        if (stop_) return;
        seen = generation_;
      }
      work(worker);
      {
        std::lock_guard<std::mutex> lock(mutex_);
        --active_;
      }
      done_.notify_one();
    }
  }

  std::vector<std::thread> workers_;
  std::mutex mutex_, run_mutex_;
  std::condition_variable wake_, done_;
  const std::function<void(std::int64_t, std::int64_t, int)>* job_ = nullptr;
  std::int64_t count_ = 0, grain_ = 1;
  std::atomic<std::int64_t> next_{0};
  std::exception_ptr error_;
  int active_ = 0;
  std::uint64_t generation_ = 0;
  bool stop_ = false;
};

// parallel_for on the global pool.
inline void parallel_for(std::int64_t count, std::int64_t grain,
                         const std::function<void(std::int64_t, std::int64_t, int)>& body) {
  ThreadPool::global().parallel_for(count, grain, body);
}

}  // namespace difftrans
