// Exit codes of revolve and revolved (sysexits.h where one fits).
#pragma once

namespace revolve::station {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailed = 1;        // the scan started but failed; its folder says why
inline constexpr int kExitUsage = 2;         // bad command line
inline constexpr int kExitUnavailable = 69;  // EX_UNAVAILABLE: revolved is not reachable
inline constexpr int kExitBusy = 75;    // EX_TEMPFAIL: revolved refused the start (a scan runs)
inline constexpr int kExitConfig = 78;  // EX_CONFIG: the configuration is missing or invalid
inline constexpr int kExitAborted = 130;

}  // namespace revolve::station
