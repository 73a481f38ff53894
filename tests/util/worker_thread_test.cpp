#include "hlt/util/worker_thread.h"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <thread>

#include "hlt/util/error.h"

namespace hlt {
namespace {

TEST(WorkerThread, RunsTasksOnAnotherThreadOneAtATime) {
  WorkerThread worker;
  std::atomic<int> sum{0};
  std::thread::id seen;
  for (int i = 1; i <= 100; ++i) {
    worker.start([&, i] {
      sum += i;
      seen = std::this_thread::get_id();
    });
    worker.wait();
  }
  EXPECT_EQ(sum.load(), 5050);
  EXPECT_NE(seen, std::this_thread::get_id());
}

TEST(WorkerThread, RethrowsWhatTheTaskThrewAndGoesOn) {
  WorkerThread worker;
  worker.start([] { throw std::runtime_error("boom"); });
  EXPECT_THROW(worker.wait(), std::runtime_error);
  bool ran = false;
  worker.start([&] { ran = true; });
  worker.wait();
  EXPECT_TRUE(ran);
}

TEST(WorkerThread, RefusesASecondTaskWhileOneRuns) {
  WorkerThread worker;
  std::atomic<bool> release{false};
  worker.start([&] {
    while (!release)
      std::this_thread::yield();
  });
  EXPECT_THROW(worker.start([] {}), Error);
  release = true;
  worker.wait();
}

}  // namespace
}  // namespace hlt
