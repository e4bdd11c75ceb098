// Fuzzes config::Parse and every typed getter over whatever it parses: no input may crash, throw
// or hang; every number that is read is finite.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "config/config.h"

namespace {

using revolve::config::Section;

void Walk(const Section& section, const toml::table& table, int depth) {
  if (depth > 8) return;
  for (auto&& [key, node] : table) {
    const std::string_view k = key.str();
    if (auto v = section.Number(k, 0.0, -1e300, 1e300); v && !std::isfinite(*v)) std::abort();
    (void)section.Integer(k, 0, INT64_MIN, INT64_MAX);
    (void)section.Boolean(k, false);
    (void)section.String(k, "", {"a", "b"});
    (void)section.Path(k, {});
    if (auto v = section.Numbers(k, {}); v) {
      for (double x : *v) {
        if (!std::isfinite(x)) std::abort();
      }
    }
    (void)section.Strings(k, {});
    (void)section.BadValue(k, "x");
    if (auto child = section.Child(k); child && node.is_table()) {
      Walk(*child, *node.as_table(), depth + 1);
      (void)child->CheckNoUnknownKeys();
    }
  }
  (void)section.CheckNoUnknownKeys();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto document =
      revolve::config::Parse(std::string(reinterpret_cast<const char*>(data), size), "fuzz.toml");
  if (!document) return 0;
  Walk(Section::Root(*document), document->root, 0);
  return 0;
}
