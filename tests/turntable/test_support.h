// Helpers for the turntable tests that run real peers: child processes that are always killed,
// socat pty pairs, temporary directories. Header-only; test code only.
#pragma once

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "tests/support/test_files.h"

namespace revolve::turntable::test_support {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// The shared helpers (tests/support): ReadAll, and TempDir (revolve_tt_<pid>_<test>).
using revolve::test_support::ReadAll;
using revolve::test_support::TempDir;

// A child process (argv[0] is the program path) with stdout and stderr in files. The destructor
// sends SIGTERM, then SIGKILL after 2 s, and reaps it: a test never leaves a peer behind.
class ChildProcess {
 public:
  ChildProcess(std::vector<std::string> argv, fs::path log_prefix)
      : log_prefix_(std::move(log_prefix)) {
    const std::string out = log_prefix_.string() + ".out";
    const std::string err = log_prefix_.string() + ".err";
    pid_ = ::fork();
    if (pid_ == 0) {
      // Child: own process group, so a stray grandchild dies with it.
      ::setpgid(0, 0);
      FILE* o = std::freopen(out.c_str(), "w", stdout);
      FILE* e = std::freopen(err.c_str(), "w", stderr);
      (void)o;
      (void)e;
      std::vector<char*> args;
      for (std::string& a : argv) args.push_back(a.data());
      args.push_back(nullptr);
      ::execv(args[0], args.data());
      std::_Exit(127);
    }
  }
  ~ChildProcess() { Kill(); }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  pid_t pid() const { return pid_; }
  bool Running() {
    if (pid_ <= 0 || exited_) return false;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      exited_ = true;
      return false;
    }
    return true;
  }
  void Kill() {
    if (pid_ <= 0 || exited_) return;
    ::kill(pid_, SIGTERM);
    const auto until = std::chrono::steady_clock::now() + 2s;
    int status = 0;
    while (std::chrono::steady_clock::now() < until) {
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        exited_ = true;
        return;
      }
      std::this_thread::sleep_for(5ms);
    }
    ::kill(-pid_, SIGKILL);
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, &status, 0);
    exited_ = true;
  }
  std::string Output() const { return ReadAll(log_prefix_.string() + ".out"); }
  std::string Errors() const { return ReadAll(log_prefix_.string() + ".err"); }
  std::string Logs() const { return "--- stdout:\n" + Output() + "--- stderr:\n" + Errors(); }

 private:
  fs::path log_prefix_;
  pid_t pid_ = -1;
  bool exited_ = false;
};

// Waits (bounded) until `predicate` holds.
template <class Predicate>
bool WaitFor(Predicate predicate, std::chrono::milliseconds timeout) {
  const auto until = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < until) {
    if (predicate()) return true;
    std::this_thread::sleep_for(5ms);
  }
  return predicate();
}

// The TCP port a peer wrote to `file`, once it did (within `timeout`).
inline std::optional<int> WaitForPort(const fs::path& file, std::chrono::milliseconds timeout) {
  if (!WaitFor([&] { return fs::exists(file); }, timeout)) return std::nullopt;
  try {
    return std::stoi(ReadAll(file));
  } catch (...) {
    return std::nullopt;
  }
}

inline bool HaveProgram(const char* path) { return ::access(path, X_OK) == 0; }

inline constexpr char kSocat[] = "/usr/bin/socat";
inline constexpr char kPython[] = "/usr/bin/python3";

// A fresh pseudo-terminal pair made by socat: `a` and `b` are linked to each other. Each pair
// has links of its own names: a pair made right after another in the same folder must not find
// the previous socat's links (left while it exits, or pointing at a pts number now reused).
class PtyPair {
 public:
  explicit PtyPair(const fs::path& dir)
      : serial_(NextSerial()),
        a_(dir / ("pty_a" + std::to_string(serial_))),
        b_(dir / ("pty_b" + std::to_string(serial_))),
        socat_({kSocat, "-d", "-d", "pty,raw,echo=0,link=" + a_.string(),
                "pty,raw,echo=0,link=" + b_.string()},
               dir / "socat") {
    ready_ = WaitFor([&] { return fs::exists(a_) && fs::exists(b_); }, 3000ms);
  }
  bool ready() const { return ready_; }
  const fs::path& a() const { return a_; }
  const fs::path& b() const { return b_; }
  std::string Logs() const { return socat_.Logs(); }

 private:
  static int NextSerial() {
    static std::atomic<int> next{0};
    return next++;
  }

  int serial_;
  fs::path a_;
  fs::path b_;
  ChildProcess socat_;
  bool ready_ = false;
};

}  // namespace revolve::turntable::test_support
