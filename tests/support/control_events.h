// Reading the events a revolved control connection streams (tests of the daemon). Test code only.
#pragma once

#include <chrono>
#include <set>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "station/commands/control_client.h"

namespace revolve::test_support {

// The events `client` receives until one whose "state" is in `states` (the last one returned),
// polling every `poll`; a receive error or no such event within `timeout` is a test failure
// (the events so far are returned).
inline std::vector<nlohmann::json> EventsUntil(station::ControlClient& client,
                                               const std::set<std::string>& states,
                                               std::chrono::milliseconds timeout,
                                               std::chrono::milliseconds poll) {
  std::vector<nlohmann::json> events;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    auto line = client.Receive(poll);
    if (!line) {
      if (line.error().code == ErrorCode::kTimeout) continue;
      ADD_FAILURE() << line.error().message;
      return events;
    }
    if (!line->contains("event")) continue;
    events.push_back((*line)["event"]);
    const nlohmann::json& state = events.back()["state"];
    if (state.is_string() && states.contains(state.get<std::string>())) return events;
  }
  ADD_FAILURE() << fmt::format("no {} event within the timeout", fmt::join(states, "/"));
  return events;
}

}  // namespace revolve::test_support
