// Fuzzes the control socket's framing and request parser: no input may crash, throw or hang,
// and a reply can always be formed.
#include <cstdint>
#include <string_view>

#include "station/protocol.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  revolve::station::LineSplitter splitter(256);
  // Fed in two pieces, as a socket may deliver it.
  splitter.Append(bytes.substr(0, size / 2));
  splitter.Append(bytes.substr(size / 2));
  for (auto item = splitter.Next(); item.has_value(); item = splitter.Next()) {
    nlohmann::json id;
    auto request = revolve::station::ParseRequest(item->line, &id);
    if (request) {
      (void)revolve::station::OkLine(id);
    } else {
      (void)revolve::station::ErrorLine(id, request.error());
    }
  }
  nlohmann::json id;
  (void)revolve::station::ParseRequest(bytes, &id);
  return 0;
}
