#include "station/signal_stop.h"

#include <poll.h>
#include <sys/eventfd.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdint>

namespace revolve::station {

SignalStop::SignalStop() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  wake_fd_ = UniqueFd(::eventfd(0, EFD_CLOEXEC));
  if (!wake_fd_.valid()) return;
  sigset_t old;
  pthread_sigmask(SIG_BLOCK, &set, &old);
  signal_fd_ = UniqueFd(::signalfd(-1, &set, SFD_CLOEXEC));
  if (!signal_fd_.valid()) {
    pthread_sigmask(SIG_SETMASK, &old, nullptr);
    return;
  }
  // Blocks in poll until a signal or the destructor's wake-up: no timeout to wait out.
  watcher_ = std::jthread([this] {
    pollfd fds[2] = {{signal_fd_.get(), POLLIN, 0}, {wake_fd_.get(), POLLIN, 0}};
    for (;;) {
      if (::poll(fds, 2, -1) < 0) {
        if (errno == EINTR) continue;
        return;
      }
      if (fds[1].revents != 0) return;
      if (fds[0].revents != 0) {
        signalfd_siginfo info{};
        if (::read(signal_fd_.get(), &info, sizeof(info)) == sizeof(info)) source_.request_stop();
      }
    }
  });
}

SignalStop::~SignalStop() {
  if (!watcher_.joinable()) return;
  // An eventfd write fails only when its counter would overflow, never from 0 to 1. The
  // watcher is joined when watcher_ is destroyed, before the descriptors it polls.
  const std::uint64_t one = 1;
  [[maybe_unused]] const ssize_t written = ::write(wake_fd_.get(), &one, sizeof(one));
}

}  // namespace revolve::station
