#include "base/log.h"

#include <mutex>

#include <spdlog/sinks/stdout_color_sinks.h>

namespace revolve {

std::shared_ptr<spdlog::logger> Logger(const std::string& name) {
  static std::mutex mutex;
  std::lock_guard lock(mutex);
  if (auto existing = spdlog::get(name)) return existing;
  auto logger = spdlog::stderr_color_mt(name);
  logger->set_pattern("[%H:%M:%S.%e] [%n] [%^%l%$] %v");
  return logger;
}

}  // namespace revolve
