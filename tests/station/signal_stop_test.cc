// SIGINT and SIGTERM become a stop request of the running command (station/signal_stop.h). In a
// binary of its own: a process-directed signal must find every thread with it blocked, and no
// other test starts threads here.
#include "station/signal_stop.h"

#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include <gtest/gtest.h>

namespace revolve::station {
namespace {

// Whether `token` is stopped within a generous deadline (a loaded machine is slow, never this
// slow).
bool StoppedSoon(const std::stop_token& token) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (!token.stop_requested() && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return token.stop_requested();
}

TEST(SignalStop, SigtermAndSigintRequestTheStopAndEndNothingElse) {
  for (const int signal : {SIGTERM, SIGINT}) {
    SignalStop signals;
    EXPECT_FALSE(signals.token().stop_requested());
    ASSERT_EQ(::kill(::getpid(), signal), 0);
    EXPECT_TRUE(StoppedSoon(signals.token())) << "signal " << signal;
    // Still running: the signal was taken, not acted on by its default.
  }
}

TEST(SignalStop, EndsWithoutASignalAndAnotherWatchesAfterIt) {
  { const SignalStop unused; }  // joins its watcher without any signal having come
  SignalStop again;
  EXPECT_FALSE(again.token().stop_requested());
  ASSERT_EQ(::kill(::getpid(), SIGTERM), 0);
  EXPECT_TRUE(StoppedSoon(again.token()));
}

}  // namespace
}  // namespace revolve::station
