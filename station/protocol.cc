#include "station/protocol.h"

#include <algorithm>

#include <fmt/format.h>

namespace revolve::station {
namespace {

nlohmann::json WithId(const nlohmann::json& id, nlohmann::json j) {
  if (!id.is_null()) j["id"] = id;
  return j;
}

// error_handler_t::replace: a reply never throws on bytes that are not UTF-8.
std::string Dump(const nlohmann::json& j) {
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

}  // namespace

bool IsValidScanId(std::string_view id) {
  if (id.empty() || id.size() > kMaxNameBytes || id == "." || id == "..") return false;
  return std::all_of(id.begin(), id.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
           c == '_' || c == '-';
  });
}

Expected<Request> ParseRequest(std::string_view line, nlohmann::json* id) {
  if (id) *id = nullptr;
  const nlohmann::json j = nlohmann::json::parse(line.begin(), line.end(), nullptr, false);
  if (j.is_discarded()) {
    return MakeError(ErrorCode::kProtocol,
                     "not JSON: send one JSON object per line, e.g. {\"cmd\": \"status\"}");
  }
  if (!j.is_object()) {
    return MakeError(ErrorCode::kProtocol,
                     "a request is a JSON object, e.g. {\"cmd\": \"status\"}");
  }
  Request request;
  if (auto it = j.find("id"); it != j.end()) {
    if (!it->is_primitive()) {
      return MakeError(ErrorCode::kProtocol, "\"id\" must be a string, number, bool or null");
    }
    request.id = *it;
    if (id) *id = *it;
  }
  auto cmd = j.find("cmd");
  if (cmd == j.end() || !cmd->is_string()) {
    return MakeError(ErrorCode::kProtocol,
                     "missing \"cmd\" (one of start, abort, status, watch, list)");
  }
  const std::string& name = cmd->get_ref<const std::string&>();
  if (name == "status") {
    request.kind = RequestKind::kStatus;
  } else if (name == "start") {
    request.kind = RequestKind::kStart;
  } else if (name == "abort") {
    request.kind = RequestKind::kAbort;
  } else if (name == "watch") {
    request.kind = RequestKind::kWatch;
  } else if (name == "list") {
    request.kind = RequestKind::kList;
  } else {
    return MakeError(
        ErrorCode::kBadInput,
        fmt::format("unknown command \"{}\" (one of start, abort, status, watch, list)",
                    name.substr(0, kMaxNameBytes)));
  }
  auto string_field = [&](const char* key, std::optional<std::string>& out) -> Expected<void> {
    auto it = j.find(key);
    if (it == j.end() || it->is_null()) return {};
    if (request.kind != RequestKind::kStart) {
      return MakeError(ErrorCode::kBadInput, fmt::format("\"{}\" belongs to start only", key));
    }
    if (!it->is_string()) {
      return MakeError(ErrorCode::kProtocol, fmt::format("\"{}\" must be a string", key));
    }
    const std::string& value = it->get_ref<const std::string&>();
    if (value.empty() || value.size() > kMaxNameBytes) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("\"{}\" must have 1 to {} bytes", key, kMaxNameBytes));
    }
    out = value;
    return {};
  };
  if (auto r = string_field("recipe", request.recipe); !r) return std::unexpected(r.error());
  if (auto r = string_field("resume", request.resume); !r) return std::unexpected(r.error());
  if (request.resume && !IsValidScanId(*request.resume)) {
    return MakeError(ErrorCode::kBadInput,
                     "\"resume\" must name a scan folder ([A-Za-z0-9._-], see `revolve list`)");
  }
  if (request.resume && request.recipe) {
    return MakeError(
        ErrorCode::kBadInput,
        "a resumed scan keeps its own recipe: give \"resume\" or \"recipe\", not both");
  }
  return request;
}

std::string OkLine(const nlohmann::json& id, nlohmann::json fields) {
  nlohmann::json j = {{"ok", true}};
  for (auto& [key, value] : fields.items()) j[key] = std::move(value);
  return Dump(WithId(id, std::move(j)));
}

std::string ErrorLine(const nlohmann::json& id, const Error& error) {
  return Dump(WithId(
      id,
      {{"ok", false}, {"error", {{"code", ToString(error.code)}, {"message", error.message}}}}));
}

std::string EventLine(const ScanEvent& event) { return Dump({{"event", event.ToJson()}}); }

void LineSplitter::Append(std::string_view bytes) {
  while (!bytes.empty()) {
    const std::size_t newline = bytes.find('\n');
    const std::string_view chunk = bytes.substr(0, newline);
    if (skipping_) {
      if (newline == std::string_view::npos) return;
      skipping_ = false;
      bytes.remove_prefix(newline + 1);
      continue;
    }
    if (partial_.size() + chunk.size() > max_) {
      items_.push_back(Item{Kind::kTooLong, {}});
      partial_.clear();
      if (newline == std::string_view::npos) {
        skipping_ = true;
        return;
      }
      bytes.remove_prefix(newline + 1);
      continue;
    }
    partial_.append(chunk);
    if (newline == std::string_view::npos) return;
    if (!partial_.empty() && partial_.back() == '\r') partial_.pop_back();
    items_.push_back(Item{Kind::kLine, std::move(partial_)});
    partial_.clear();
    bytes.remove_prefix(newline + 1);
  }
}

std::optional<LineSplitter::Item> LineSplitter::Next() {
  if (items_.empty()) return std::nullopt;
  Item item = std::move(items_.front());
  items_.pop_front();
  return item;
}

}  // namespace revolve::station
