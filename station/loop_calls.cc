#include "station/loop_calls.h"

#include <future>
#include <memory>

namespace revolve::station {

Expected<nlohmann::json> LoopCalls::Run(Call call, std::chrono::milliseconds timeout) {
  auto task = std::make_shared<std::packaged_task<Expected<nlohmann::json>()>>(std::move(call));
  std::future<Expected<nlohmann::json>> result = task->get_future();
  {
    std::lock_guard lock(mutex_);
    if (closed_) return MakeError(ErrorCode::kBusy, "revolved is stopping");
    pending_.push_back([task] { (*task)(); });
  }
  wake_();
  if (result.wait_for(timeout) != std::future_status::ready) {
    return MakeError(ErrorCode::kTimeout,
                     "revolved's main loop did not answer in time (is it stuck opening a device?)");
  }
  try {
    return result.get();
  } catch (const std::future_error&) {  // dropped by Close()
    return MakeError(ErrorCode::kBusy, "revolved is stopping");
  }
}

void LoopCalls::RunPending() {
  std::deque<std::function<void()>> calls;
  {
    std::lock_guard lock(mutex_);
    calls.swap(pending_);
  }
  for (auto& call : calls) call();
}

void LoopCalls::Close() {
  std::deque<std::function<void()>> dropped;
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
    dropped.swap(pending_);
  }
  // Destroying the tasks unblocks their callers (broken promise).
}

}  // namespace revolve::station
