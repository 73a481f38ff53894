// hlt::WorkerThread: one persistent thread that runs one task at a time, so that a loop can hand a piece of
// its work to a second core every iteration without paying for a thread's creation each time.
#pragma once

#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>

namespace hlt {

class WorkerThread {
 public:
  WorkerThread();
  // Waits for the running task (if any) and joins the thread.
  ~WorkerThread();
  WorkerThread(const WorkerThread&) = delete;
  WorkerThread& operator=(const WorkerThread&) = delete;

  // Starts `task` on the worker. Precondition: no task is running (wait() was called since the last start).
  void start(std::function<void()> task);
  // Blocks until the task has finished; rethrows what it threw.
  void wait();

 private:
  void loop();
  std::mutex mutex_;
  std::condition_variable cv_;
  std::function<void()> task_;
  std::exception_ptr error_;
  bool busy_ = false, stop_ = false;
  std::thread thread_;
};

}  // namespace hlt
