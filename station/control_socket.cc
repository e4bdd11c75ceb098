#include "station/control_socket.h"

#include <grp.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

#include <fmt/format.h>

namespace revolve::station {
namespace {

Error Errno(ErrorCode code, std::string what, int err) {
  return Error{code, fmt::format("{}: {}", what, std::strerror(err))};
}

}  // namespace

Expected<UniqueFd> BindControlSocket(const std::filesystem::path& path, const DaemonOptions& o) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const std::string p = path.string();
  if (p.size() >= sizeof(addr.sun_path)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("daemon.socket: {} is longer than a Unix socket path may be", p));
  }
  std::memcpy(addr.sun_path, p.c_str(), p.size() + 1);
  std::error_code ec;
  if (path.has_parent_path()) {
    std::filesystem::create_directories(path.parent_path(), ec);
    if (ec) {
      return MakeError(ErrorCode::kIo, fmt::format("cannot create {} for the control socket: {}",
                                                   path.parent_path().string(), ec.message()));
    }
  }
  struct stat st {};
  if (::lstat(p.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode)) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("daemon.socket: {} exists and is not a socket; remove it or "
                                   "choose another path",
                                   p));
    }
    UniqueFd probe(::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0));
    if (probe.valid() &&
        ::connect(probe.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) == 0) {
      return MakeError(
          ErrorCode::kBusy,
          fmt::format("another revolved is serving {} (systemctl status revolved)", p));
    }
    ::unlink(p.c_str());  // stale: left by a daemon that died
  }
  UniqueFd fd(::socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
  if (!fd.valid()) return std::unexpected(Errno(ErrorCode::kIo, "socket(AF_UNIX)", errno));
  if (::bind(fd.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
    return std::unexpected(Errno(ErrorCode::kIo, fmt::format("cannot bind {}", p), errno));
  }
  if (::chmod(p.c_str(), static_cast<mode_t>(o.socket_mode)) != 0) {
    return std::unexpected(Errno(ErrorCode::kIo, fmt::format("chmod {}", p), errno));
  }
  if (!o.socket_group.empty()) {
    group grp{};
    group* found = nullptr;
    std::vector<char> buf(16384);
    if (::getgrnam_r(o.socket_group.c_str(), &grp, buf.data(), buf.size(), &found) != 0 ||
        found == nullptr) {
      ::unlink(p.c_str());
      return MakeError(
          ErrorCode::kBadInput,
          fmt::format("daemon.socket_group: there is no group \"{}\"", o.socket_group));
    }
    if (::chown(p.c_str(), static_cast<uid_t>(-1), grp.gr_gid) != 0) {
      const int err = errno;
      ::unlink(p.c_str());
      return std::unexpected(
          Errno(ErrorCode::kIo,
                fmt::format("cannot give {} to group {} (is revolved's user in that group?)", p,
                            o.socket_group),
                err));
    }
  }
  if (::listen(fd.get(), 64) != 0) {
    return std::unexpected(Errno(ErrorCode::kIo, fmt::format("listen {}", p), errno));
  }
  return fd;
}

}  // namespace revolve::station
