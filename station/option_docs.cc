// The descriptions of [scan], [station], [station.simulate], [daemon], [operator] and
// [recipes.NAME] for the configuration reference (docs/configuration.md, made by
// `revolve check-config --reference`). The types, defaults and ranges come from the parser
// itself; a key it reads with no description here fails the test config_reference.
#include "station/station_config.h"

namespace revolve::station {
namespace {

constexpr config::TableDoc kTables[] = {
    {"scan", ""},
    {"station", ""},
    {"station.simulate",
     "Fault injection for tests and demos. Drive faults need `[turntable] backend = \"mock\"` and "
     "camera loss and bad frames need the synthetic or replay camera; otherwise the configuration "
     "is refused. Captures and moves are counted from the start of `revolve scan` or `revolved`."},
    {"daemon", ""},
    {"operator", ""},
    {"web",
     "The live web console and HTTP API of revolved ([web console](web-console.md)). A listen "
     "address other than loopback needs `token_file`."},
    {"recipes.NAME",
     "Named scans; see [Recipes](station.md#recipes). Each key overrides one key of the base "
     "configuration; an absent key leaves it as it is."},
};

constexpr config::KeyDoc kKeys[] = {
    {"scan", "stops", "count", "stops in one scan; `stops × step_deg` must not exceed 360"},
    {"scan", "step_deg", "degrees", "plate rotation between stops"},
    {"scan", "settle_ms", "ms", "wait after the drive reports in position, before capturing"},
    {"scan", "move_timeout_s", "s", "a move (or homing) that takes longer fails the scan"},
    {"scan", "capture_timeout_s", "s",
     "a capture that takes longer fails (and is re-tried, see `[station] camera_retries`)"},
    {"station", "recipe", "name",
     "recipe of the start button, `revolve start` and `revolve scan` without `--recipe`", "", "",
     "`default` or the NAME of a `[recipes.NAME]`"},
    {"station", "scans_dir", "",
     "where revolved creates `<id>/`; relative: under `$STATE_DIRECTORY` (systemd's "
     "StateDirectory), else the working directory",
     "", "", "non-empty"},
    {"station", "camera_retries", "count",
     "re-tries of a failed capture (reopening the camera) before the scan fails"},
    {"station", "camera_retry_delay_ms", "ms", "wait before a re-try"},
    {"station", "min_free_mb", "MiB",
     "a start with less free space in `scans_dir` is refused; 0 = no check"},
    {"station.simulate", "drive_fault", "", "a mock turntable fault"},
    {"station.simulate", "drive_fault_move", "index", "the move that faults"},
    {"station.simulate", "drive_fault_count", "count", "consecutive moves that fault"},
    {"station.simulate", "drive_fault_at", "fraction", "of the move's time, when it strikes"},
    {"station.simulate", "drive_alarm_code", "", "the code of `alarm`"},
    {"station.simulate", "camera_fail_after", "captures",
     "captures before the camera is lost (no_device); -1: never"},
    {"station.simulate", "camera_fail_count", "captures", "consecutive captures that fail"},
    {"station.simulate", "camera_glitch", "",
     "bad frames for the quality gates: black, gain × 4, Gaussian blur σ 6 px"},
    {"station.simulate", "camera_glitch_after", "captures", "captures before the first bad frame"},
    {"station.simulate", "camera_glitch_count", "captures", "consecutive bad frames"},
    {"station.simulate", "disk_limit_bytes", "bytes",
     "simulated disk space of a scan folder (\"No space left on device\" beyond it); 0: unlimited"},
    {"daemon", "socket", "", "the control socket", "", "", "non-empty, < 108 bytes"},
    {"daemon", "socket_mode", "octal", "its permissions", "string or integer", "`\"0660\"`",
     "`\"0000\"`–`\"0777\"` (a string, or a TOML octal `0o660`)"},
    {"daemon", "socket_group", "group name", "its group", "", "",
     "an existing group; empty: the daemon's group"},
    {"daemon", "max_clients", "count", "simultaneous connections"},
    {"daemon", "max_request_bytes", "bytes", "longest request line"},
    {"daemon", "idle_timeout_s", "s",
     "a client that neither sends nor watches is closed after this long (and gives up its slot "
     "to a newcomer when every slot is taken)"},
    {"operator", "chip", "", "name, `/dev` path or label (`\"pinctrl-bcm2711\"`)"},
    {"operator", "start_button", "line", "start button input", "integer or string", "none",
     "a line offset 0–1023 or a line name (`\"GPIO17\"`)"},
    {"operator", "start_button_active_low", "", "the start button pulls the line low"},
    {"operator", "abort_button", "line", "optional abort button", "integer or string", "none",
     "a line offset 0–1023 or a line name (`\"GPIO17\"`)"},
    {"operator", "abort_button_active_low", "", "the abort button pulls the line low"},
    {"operator", "led", "line", "status LED output", "integer or string", "none",
     "a line offset 0–1023 or a line name (`\"GPIO17\"`)"},
    {"operator", "led_active_low", "", "the LED is on when the line is low"},
    {"operator", "lamp", "line", "lamp relay output, on during a scan", "integer or string", "none",
     "a line offset 0–1023 or a line name (`\"GPIO17\"`)"},
    {"operator", "lamp_active_low", "", "the lamp relay is on when the line is low"},
    {"operator", "bias", "", "bias of the button inputs (kernel ≥ 5.5)"},
    {"operator", "debounce_ms", "ms", "software debounce of the buttons"},
    {"recipes.NAME", "stops", "count", "overrides `[scan] stops`"},
    {"recipes.NAME", "step_deg", "", "overrides `[scan] step_deg`"},
    {"recipes.NAME", "settle_ms", "", "overrides `[scan] settle_ms`"},
    {"recipes.NAME", "exposure_us", "",
     "overrides `[camera.v4l2]` / `[camera.libcamera] exposure_us` (only with those two backends)"},
    {"recipes.NAME", "segment", "", "overrides `[segment] method`, with its values"},
    {"recipes.NAME", "threshold", "grey level", "overrides `[segment] threshold`"},
    {"recipes.NAME", "method", "", "overrides `[reconstruct] method`, with its values"},
    {"recipes.NAME", "resolution", "voxels", "overrides `[reconstruct] resolution`"},
    {"recipes.NAME", "formats", "", "overrides `[reconstruct] formats`, with its values"},
    {"web", "listen", "host:port",
     "where the console listens; `\"\"` turns it off; port 0 takes any free port"},
    {"web", "token_file", "",
     "a file holding the access token: POSTs need it on loopback, every API request elsewhere"},
    {"web", "max_connections", "count", "simultaneous HTTP connections"},
    {"web", "max_request_bytes", "bytes", "largest request (headers and body)"},
    {"web", "timeout_s", "s", "read and write timeout of a connection"},
};

}  // namespace

config::OptionDocs ReferenceDocs() { return {kTables, kKeys}; }

}  // namespace revolve::station
