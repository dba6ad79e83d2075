#pragma once
// A thread of its own that runs jobs one at a time, first posted first run: the LiDAR sweeps
// are cast and their cones detected on it while the physics goes on. Because the jobs run in
// the order they were posted, a job may use what the earlier ones left (the noise generator,
// a sweep cast in parts) without any more synchronisation.
//
// Jobs posted with post_later() form a second queue, run in their own order but only while no
// post() job is waiting: a SLAM lane's scoring, which nothing in the loop waits for, never
// delays the next update, which the loop does wait for. The two queues must not share state.

#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <thread>
#include <type_traits>

namespace conesim::sim {

/// Runs posted jobs on one thread, in the order they were posted (post_later()'s after post()'s).
class WorkerThread {
 public:
  /// Starts the thread.
  WorkerThread();
  /// Runs the jobs still queued, then stops the thread.
  ~WorkerThread();
  WorkerThread(const WorkerThread&) = delete;
  WorkerThread& operator=(const WorkerThread&) = delete;

  /// Queues a job; its result (or the exception it threw) arrives through the future. The job,
  /// and whatever it captured, is destroyed once it has run, before its result arrives: a
  /// future kept for later holds the result only (a packaged task's future would keep the job
  /// too, and a run that keeps one future per frame would grow by every frame's captures).
  template <typename Job>
  std::future<std::invoke_result_t<Job&>> post(Job job) {
    return post_to(jobs_, std::move(job));
  }

  /// Queues a job behind every post() job waiting now or posted before it starts; among
  /// themselves these jobs run in the order posted.
  template <typename Job>
  std::future<std::invoke_result_t<Job&>> post_later(Job job) {
    return post_to(later_, std::move(job));
  }

  /// Waits until every job posted so far (with post() or post_later()) has run.
  void wait_idle();

  /// Drops the jobs not yet started (their futures report a broken promise); the one running
  /// finishes. An interrupted run stops this way instead of working through a backlog.
  void drop_queued();

 private:
  using Queue = std::deque<std::function<void()>>;

  template <typename Job>
  std::future<std::invoke_result_t<Job&>> post_to(Queue& queue, Job job) {
    using Result = std::invoke_result_t<Job&>;
    auto promise = std::make_shared<std::promise<Result>>();
    std::future<Result> result = promise->get_future();
    auto held = std::make_shared<Job>(std::move(job));
    enqueue(
        [promise, held]() mutable {
          try {
            if constexpr (std::is_void_v<Result>) {
              (*held)();
              held.reset();
              promise->set_value();
            } else {
              Result value = (*held)();
              held.reset();
              promise->set_value(std::move(value));
            }
          } catch (...) {
            held.reset();
            promise->set_exception(std::current_exception());
          }
        },
        queue);
    return result;
  }

  void enqueue(std::function<void()> job, Queue& queue);
  void run();

  std::mutex mutex_;
  std::condition_variable wake_;
  // post()'s jobs, and post_later()'s, which run only while the first queue is empty
  Queue jobs_;
  Queue later_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace conesim::sim
