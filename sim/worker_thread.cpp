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
  // an empty job in the second queue runs once both queues are empty of what was posted before
  post_later([] {}).wait();
}

void WorkerThread::drop_queued() {
  // destroyed outside the lock: a job's captures may be large
  Queue dropped, dropped_later;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    dropped.swap(jobs_);
    dropped_later.swap(later_);
  }
}

void WorkerThread::enqueue(std::function<void()> job, Queue& queue) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    queue.push_back(std::move(job));
  }
  wake_.notify_one();
}

void WorkerThread::run() {
  for (;;) {
    // the next job, or the end once stopping with nothing left to run
    std::function<void()> job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !jobs_.empty() || !later_.empty(); });
      Queue& queue = !jobs_.empty() ? jobs_ : later_;
      if (queue.empty()) return;
      job = std::move(queue.front());
      queue.pop_front();
    }
    // (post() hands the job's result or exception to its future)
    job();
  }
}

}  // namespace conesim::sim
