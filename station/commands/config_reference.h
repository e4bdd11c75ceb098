// The configuration reference (docs/configuration.md): every table and key the station's
// configuration parsers read, with its type, default, range and description. The types,
// defaults and ranges are recorded from the parsers themselves (config/reference.h), so the
// reference cannot drift from the code; the descriptions sit next to each module's parser.
#pragma once

#include <string>
#include <vector>

#include "base/error.h"

namespace revolve::station {

// The reference as Markdown (what `revolve check-config --reference` prints). Parses a few
// probe configurations with recording on, so that keys read only on some branch (Modbus TCP,
// GPIO lines, recipes) are recorded too. Errors: a probe that no longer parses.
Expected<std::string> ConfigReferenceMarkdown();

// What the descriptions lack or have in excess, one line each; empty when every key read has a
// description and every description names a key that is read.
Expected<std::vector<std::string>> ConfigReferenceGaps();

}  // namespace revolve::station
