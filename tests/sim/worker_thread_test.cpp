// The worker thread of the LiDAR and of each SLAM lane: jobs run one at a time in the order
// posted (the later queue behind the first), results and errors come back through the futures.

#include "sim/worker_thread.hpp"

#include <gtest/gtest.h>

#include <future>
#include <memory>
#include <stdexcept>
#include <thread>
#include <vector>

namespace conesim::sim {
namespace {

TEST(WorkerThread, RunsJobsInTheOrderPosted) {
  std::vector<int> order;  // touched by the worker only until wait_idle returns
  WorkerThread worker;
  for (int i = 0; i < 100; ++i)
    worker.post([&order, i] {
      // an early job that takes longer must still finish before the next one starts
      if (i % 10 == 0) std::this_thread::sleep_for(std::chrono::microseconds(200));
      order.push_back(i);
    });
  worker.wait_idle();
  ASSERT_EQ(order.size(), 100u);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(order[i], i);
}

TEST(WorkerThread, ResultsAndErrorsComeThroughTheFuture) {
  WorkerThread worker;
  std::future<int> answer = worker.post([] { return 42; });
  std::future<void> failed = worker.post([] { throw std::runtime_error("no poses"); });
  std::future<int> after = worker.post([] { return 7; });
  EXPECT_EQ(answer.get(), 42);
  EXPECT_THROW(failed.get(), std::runtime_error);
  // a failed job does not stop the ones after it
  EXPECT_EQ(after.get(), 7);
}

TEST(WorkerThread, AJobsCapturesGoOnceItHasRunThoughItsFutureIsKept) {
  // a run keeps one future per SLAM frame until its end: a frame's captures (its cones, the
  // estimate's map) held by the future made a 100-lap run grow by 6 MB a lap
  WorkerThread worker;
  auto frame = std::make_shared<std::vector<double>>(1000, 1.0);
  const std::weak_ptr<std::vector<double>> alive = frame;
  std::future<double> kept = worker.post([frame] { return frame->front(); });
  frame.reset();
  ASSERT_EQ(kept.wait_for(std::chrono::seconds(10)), std::future_status::ready);
  EXPECT_TRUE(alive.expired());
  EXPECT_EQ(kept.get(), 1.0);
}

TEST(WorkerThread, LaterJobsWaitBehindTheOthersAndKeepTheirOwnOrder) {
  // a SLAM lane's scoring (post_later) must not hold up its next update (post)
  std::vector<int> order;  // touched by the worker only until wait_idle returns
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  WorkerThread worker;
  worker.post([released] { released.wait(); });  // keeps the thread busy while we queue
  worker.post_later([&order] { order.push_back(10); });
  worker.post([&order] { order.push_back(1); });
  worker.post_later([&order] { order.push_back(11); });
  worker.post([&order] { order.push_back(2); });
  release.set_value();
  worker.wait_idle();
  EXPECT_EQ(order, (std::vector<int>{1, 2, 10, 11}));
  // wait_idle also waits for the later queue
  worker.post_later([&order] { order.push_back(12); });
  worker.wait_idle();
  EXPECT_EQ(order.back(), 12);
}

TEST(WorkerThread, RunsWhatIsQueuedBeforeStopping) {
  int done = 0;
  {
    WorkerThread worker;
    for (int i = 0; i < 20; ++i) worker.post([&done] { ++done; });
    for (int i = 0; i < 5; ++i) worker.post_later([&done] { ++done; });
  }
  EXPECT_EQ(done, 25);
}

}  // namespace
}  // namespace conesim::sim
