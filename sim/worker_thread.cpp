#include "sim/worker_thread.hpp"

namespace conesim::sim {

WorkerThread::WorkerThread() : thread_([this] { run(); }) {}

WorkerThread::~WorkerThread() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_one();
  thread_.join();
}

void WorkerThread::wait_idle() {
  // the jobs run in order: once an empty job has run, so have all posted before it
  post([] {}).wait();
}

void WorkerThread::drop_queued() {
  // destroyed outside the lock: a job's captures may be large
  std::deque<std::function<void()>> dropped;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    dropped.swap(jobs_);
  }
}

void WorkerThread::enqueue(std::function<void()> job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    jobs_.push_back(std::move(job));
  }
  wake_.notify_one();
}

void WorkerThread::run() {
  for (;;) {
    // the next job, or the end once stopping with nothing left to run
    std::function<void()> job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !jobs_.empty(); });
      if (jobs_.empty()) return;
      job = std::move(jobs_.front());
      jobs_.pop_front();
    }
    // (post() hands the job's result or exception to its future)
    job();
  }
}

}  // namespace conesim::sim
