// The two lanes streamJob runs a job on (private to the slicer). The bands' lane (the thread that
// called streamJob) makes and dithers each band; the writer's lane (a thread of its own) writes them.
// A lane with nothing of its own to do joins the other lane's current work, taking the tasks of its
// parallel loops (tbb::collaborative_call_once), rather than idling: a stage that has the machine to
// itself runs on every core, and the stages still overlap wherever both lanes have work.
#pragma once

#include <tbb/collaborative_call_once.h>

#include <condition_variable>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>

namespace rodfab::slicer::detail {

enum class Lane { bands = 0, writer = 1 };

// Thrown in a lane that waits when the other lane has failed or stopped: the lane unwinds, and
// streamJob rethrows the error that stopped the pipeline.
struct LaneStopped {};

// What the two lanes share: the bands handed from one to the other, how many are alive, and each
// lane's current work. All members are thread-safe. `Item` is a shared band pointer.
template <class Item>
class PipelineLanes {
public:
  // At most `itemsInFlight` (>= 1) items are alive: reserved and not yet released.
  explicit PipelineLanes(int itemsInFlight) : itemsInFlight_(itemsInFlight) {}

  // Runs `work` on the calling thread as `lane`'s current work, which the other lane joins while it
  // waits. Call it inside the task arena whose threads `work`'s parallel loops should use. What `work`
  // throws reaches the caller.
  template <class F>
  void runShared(Lane lane, F&& work) {
    auto flag = std::make_shared<tbb::collaborative_once_flag>();
    tbb::collaborative_call_once(*flag, [&] {
      publish(lane, flag);
      try {
        work();
      } catch (...) {
        publish(lane, nullptr);
        throw;
      }
      publish(lane, nullptr);
    });
  }

  // Bands' lane: waits, helping the writer, until fewer than itemsInFlight items are alive, and counts
  // one more. Throws LaneStopped once the pipeline stopped.
  void reserve() {
    std::unique_lock lock(mutex_);
    waitHelping(Lane::writer, lock, [&] { return alive_ < itemsInFlight_; });
    ++alive_;
  }
  // Bands' lane: a reserved item, ready for the writer.
  void handOver(Item item) {
    std::lock_guard lock(mutex_);
    ready_.push_back(std::move(item));
    changed_.notify_all();
  }
  // Bands' lane: no more items; waits, helping the writer, until it has released every item.
  void closeAndDrain() {
    std::unique_lock lock(mutex_);
    closed_ = true;
    changed_.notify_all();
    waitHelping(Lane::writer, lock, [&] { return alive_ == 0; });
  }

  // Writer's lane: the next item, waiting (and helping the bands' lane) until one is handed over;
  // null once the lanes are closed and drained. Throws LaneStopped once the pipeline stopped.
  Item take() {
    std::unique_lock lock(mutex_);
    waitHelping(Lane::bands, lock, [&] { return !ready_.empty() || closed_; });
    if (ready_.empty()) return nullptr;
    Item item = std::move(ready_.front());
    ready_.pop_front();
    return item;
  }
  // Joins `lane`'s current work if it has some, until it ends.
  void helpWith(Lane lane) {
    std::shared_ptr<tbb::collaborative_once_flag> work;
    {
      std::lock_guard lock(mutex_);
      work = current_[int(lane)];
    }
    if (work) tbb::collaborative_call_once(*work, [] {});
  }
  // Writer's lane: an item taken is done with (dropped).
  void release() {
    std::lock_guard lock(mutex_);
    --alive_;
    changed_.notify_all();
  }

  // Either lane: stops the pipeline; the first error given is the one kept. Waiting lanes throw
  // LaneStopped.
  void stop(std::exception_ptr error) {
    std::lock_guard lock(mutex_);
    if (!error_) error_ = error;
    stopped_ = true;
    changed_.notify_all();
  }
  std::exception_ptr error() const {
    std::lock_guard lock(mutex_);
    return error_;
  }

private:
  // Waits until `ready()` holds (under the lock), joining `other`'s current work whenever it has some.
  template <class Ready>
  void waitHelping(Lane other, std::unique_lock<std::mutex>& lock, Ready ready) {
    for (;;) {
      if (stopped_) throw LaneStopped{};
      if (ready()) return;
      if (std::shared_ptr<tbb::collaborative_once_flag> work = current_[int(other)]) {
        lock.unlock();
        // The work is running (it was published from inside its call): this joins it until it ends.
        // Called after it ended, the flag is done and this returns at once.
        tbb::collaborative_call_once(*work, [] {});
        lock.lock();
        continue;
      }
      changed_.wait(lock);
    }
  }

  void publish(Lane lane, std::shared_ptr<tbb::collaborative_once_flag> work) {
    std::lock_guard lock(mutex_);
    current_[int(lane)] = std::move(work);
    changed_.notify_all();
  }

  const int itemsInFlight_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Item> ready_;
  int alive_ = 0;
  bool closed_ = false, stopped_ = false;
  std::exception_ptr error_;
  std::shared_ptr<tbb::collaborative_once_flag> current_[2];
};

}  // namespace rodfab::slicer::detail
