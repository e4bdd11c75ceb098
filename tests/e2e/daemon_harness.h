// Test harness for the real revolved and revolve processes: spawn with a timeout, stop, read
// /proc figures. Every child is killed in the destructor, so a failing test never leaves one
// behind.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "tests/support/test_files.h"

namespace revolve::e2e {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

using test_support::ReadAll;

// A child process with stdout and stderr in files.
class Child {
 public:
  Child() = default;
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;
  Child(Child&& other) noexcept
      : pid_(std::exchange(other.pid_, -1)), exit_code_(other.exit_code_) {}
  Child& operator=(Child&& other) noexcept {
    if (this != &other) {
      Kill();
      pid_ = std::exchange(other.pid_, -1);
      exit_code_ = other.exit_code_;
    }
    return *this;
  }
  ~Child() { Kill(); }

  // `env` entries "NAME=value" are added to the environment; "WATCHDOG_PID=self" becomes the
  // child's own pid (through `sh -c 'WATCHDOG_PID=$$ exec ...'`). Everything is prepared before
  // fork(), so the child only calls async-signal-safe functions.
  static Child Spawn(const std::vector<std::string>& argv, const std::vector<std::string>& env,
                     const fs::path& out, const fs::path& err) {
    std::vector<std::string> args = argv;
    std::vector<std::string> environment;
    bool watchdog_self = false;
    for (char** e = environ; *e != nullptr; ++e) environment.emplace_back(*e);
    for (const std::string& e : env) {
      if (e == "WATCHDOG_PID=self") {
        watchdog_self = true;
        continue;
      }
      const std::string name = e.substr(0, e.find('='));
      std::erase_if(environment, [&](const std::string& x) { return x.rfind(name + "=", 0) == 0; });
      environment.push_back(e);
    }
    if (watchdog_self) {
      std::string command = "WATCHDOG_PID=$$ exec";
      for (const std::string& a : argv) command += " '" + a + "'";
      args = {"/bin/sh", "-c", command};
    }
    std::vector<char*> arg_ptrs;
    for (std::string& a : args) arg_ptrs.push_back(a.data());
    arg_ptrs.push_back(nullptr);
    std::vector<char*> env_ptrs;
    for (std::string& e : environment) env_ptrs.push_back(e.data());
    env_ptrs.push_back(nullptr);
    const std::string out_path = out.string();
    const std::string err_path = err.string();

    Child c;
    c.pid_ = ::fork();
    if (c.pid_ == 0) {
      sigset_t none;
      sigemptyset(&none);
      sigprocmask(SIG_SETMASK, &none, nullptr);
      const int o = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int r = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int in = ::open("/dev/null", O_RDONLY);
      ::dup2(in, 0);
      ::dup2(o, 1);
      ::dup2(r, 2);
      ::execve(arg_ptrs[0], arg_ptrs.data(), env_ptrs.data());
      ::_exit(127);
    }
    return c;
  }

  pid_t pid() const { return pid_; }
  bool running() const { return pid_ > 0; }

  // The exit code (128 + signal when killed), or nullopt if still running after `timeout`.
  std::optional<int> Wait(std::chrono::milliseconds timeout) {
    if (pid_ <= 0) return exit_code_;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      int status = 0;
      const pid_t r = ::waitpid(pid_, &status, WNOHANG);
      if (r == pid_) {
        pid_ = -1;
        exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        return exit_code_;
      }
      if (std::chrono::steady_clock::now() >= deadline) return std::nullopt;
      std::this_thread::sleep_for(5ms);
    }
  }

  void Signal(int sig) {
    if (pid_ > 0) ::kill(pid_, sig);
  }

  void Kill() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
  }

 private:
  pid_t pid_ = -1;
  std::optional<int> exit_code_;
};

struct CommandResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

// Runs a command to completion (killed after `timeout`).
inline CommandResult RunCommand(const std::vector<std::string>& argv,
                                const std::vector<std::string>& env, const fs::path& dir,
                                std::chrono::milliseconds timeout = 120s) {
  static int counter = 0;
  const fs::path out = dir / ("cmd_" + std::to_string(counter) + ".out");
  const fs::path err = dir / ("cmd_" + std::to_string(counter++) + ".err");
  Child child = Child::Spawn(argv, env, out, err);
  CommandResult r;
  auto code = child.Wait(timeout);
  if (!code) {
    child.Kill();
    r.exit_code = -2;  // timed out
  } else {
    r.exit_code = *code;
  }
  r.out = ReadAll(out);
  r.err = ReadAll(err);
  return r;
}

// Resident memory (kB) and open descriptors of a process.
inline long RssKb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  }
  return -1;
}

inline int OpenFds(pid_t pid) {
  int n = 0;
  std::error_code ec;
  for (auto it = fs::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec);
       it != fs::directory_iterator(); it.increment(ec)) {
    ++n;
  }
  return n;
}

}  // namespace revolve::e2e
