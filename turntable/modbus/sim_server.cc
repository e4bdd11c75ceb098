#include "turntable/modbus/sim_server.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "base/log.h"
#include "base/unique_fd.h"

namespace revolve::turntable::modbus {
namespace {

using SteadyClock = std::chrono::steady_clock;

bool WriteAll(int fd, std::span<const std::uint8_t> bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN) {
        pollfd p{fd, POLLOUT, 0};
        ::poll(&p, 1, 100);
        continue;
      }
      return false;
    }
    done += static_cast<std::size_t>(n);
  }
  return true;
}

Expected<void> WritePortFile(const std::filesystem::path& path, int port) {
  const std::filesystem::path temp = path.string() + ".tmp";
  {
    std::ofstream out(temp);
    out << port << "\n";
    if (!out) {
      return MakeError(ErrorCode::kIo, fmt::format("cannot write {}", temp.string()));
    }
  }
  std::error_code ec;
  std::filesystem::rename(temp, path, ec);
  if (ec) return MakeError(ErrorCode::kIo, fmt::format("cannot write {}", path.string()));
  return {};
}

Expected<void> ServeTcp(SimulatedDrive& drive, const SimServerOptions& options,
                        std::stop_token stop,
                        const std::function<void(const std::string&)>& on_ready) {
  auto log = Logger("turntable");
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE;
  addrinfo* info = nullptr;
  const std::string service = std::to_string(options.port);
  if (const int rc = ::getaddrinfo(options.host.c_str(), service.c_str(), &hints, &info); rc != 0) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("cannot resolve {}: {}", options.host, gai_strerror(rc)));
  }
  UniqueFd listener(::socket(info->ai_family, SOCK_STREAM | SOCK_CLOEXEC, 0));
  const int one = 1;
  ::setsockopt(listener.get(), SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  const int bound = ::bind(listener.get(), info->ai_addr, info->ai_addrlen);
  ::freeaddrinfo(info);
  if (!listener.valid() || bound != 0 || ::listen(listener.get(), 8) != 0) {
    return MakeError(ErrorCode::kIo, fmt::format("cannot listen on {}:{}: {}", options.host,
                                                 options.port, std::strerror(errno)));
  }
  sockaddr_in address{};
  socklen_t length = sizeof address;
  ::getsockname(listener.get(), reinterpret_cast<sockaddr*>(&address), &length);
  const int port = ntohs(address.sin_port);
  if (!options.port_file.empty()) {
    if (Expected<void> written = WritePortFile(options.port_file, port); !written) return written;
  }
  on_ready(fmt::format("listening on tcp {}:{}", options.host, port));

  struct Client {
    UniqueFd fd;
    std::vector<std::uint8_t> buffer;
  };
  std::vector<Client> clients;
  while (!stop.stop_requested()) {
    if (drive.LinkDown(SteadyClock::now()) && (listener.valid() || !clients.empty())) {
      log->info("simulated link drop: closing every connection and the listener");
      clients.clear();
      listener.Reset();
    }
    std::vector<pollfd> fds;
    if (listener.valid()) fds.push_back({listener.get(), POLLIN, 0});
    for (const Client& c : clients) fds.push_back({c.fd.get(), POLLIN, 0});
    const int ready = ::poll(fds.data(), fds.size(), 20);
    if (ready <= 0) continue;
    std::size_t index = 0;
    if (listener.valid()) {
      if ((fds[0].revents & POLLIN) != 0) {
        UniqueFd client(::accept4(listener.get(), nullptr, nullptr, SOCK_CLOEXEC));
        if (client.valid()) {
          ::setsockopt(client.get(), IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
          clients.push_back(Client{std::move(client), {}});
          log->debug("simulated drive: client connected");
        }
      }
      index = 1;
    }
    std::vector<std::size_t> closed;
    for (std::size_t i = 0; index + i < fds.size() && i < clients.size(); ++i) {
      if ((fds[index + i].revents & (POLLIN | POLLHUP | POLLERR)) == 0) continue;
      Client& client = clients[i];
      std::uint8_t chunk[512];
      const ssize_t n = ::read(client.fd.get(), chunk, sizeof chunk);
      if (n <= 0) {
        closed.push_back(i);
        continue;
      }
      client.buffer.insert(client.buffer.end(), chunk, chunk + n);
      while (client.buffer.size() >= 7) {
        const std::size_t pdu_length =
            static_cast<std::size_t>(client.buffer[4] << 8 | client.buffer[5]);
        if (pdu_length < 2 || pdu_length > 254) {
          client.buffer.clear();  // not Modbus: drop it all
          break;
        }
        if (client.buffer.size() < 6 + pdu_length) break;
        const std::uint16_t transaction =
            static_cast<std::uint16_t>(client.buffer[0] << 8 | client.buffer[1]);
        const std::uint8_t unit = client.buffer[6];
        const std::vector<std::uint8_t> pdu(client.buffer.begin() + 7,
                                            client.buffer.begin() + 6 + pdu_length);
        client.buffer.erase(client.buffer.begin(), client.buffer.begin() + 6 + pdu_length);
        SimReply reply = drive.Handle(pdu, SteadyClock::now());
        if (reply.action == SimReply::Action::kDrop) continue;
        const std::uint16_t answered_transaction = reply.action == SimReply::Action::kCorrupt
                                                       ? static_cast<std::uint16_t>(~transaction)
                                                       : transaction;
        const std::vector<std::uint8_t> adu = EncodeTcpAdu(answered_transaction, unit, reply.pdu);
        if (!WriteAll(client.fd.get(), adu)) closed.push_back(i);
      }
    }
    for (auto it = closed.rbegin(); it != closed.rend(); ++it) {
      clients.erase(clients.begin() + static_cast<std::ptrdiff_t>(*it));
    }
  }
  return {};
}

Expected<speed_t> BaudConstant(int baud) {
  switch (baud) {
    case 1200:
      return B1200;
    case 2400:
      return B2400;
    case 4800:
      return B4800;
    case 9600:
      return B9600;
    case 19200:
      return B19200;
    case 38400:
      return B38400;
    case 57600:
      return B57600;
    case 115200:
      return B115200;
    case 230400:
      return B230400;
    case 460800:
      return B460800;
    case 500000:
      return B500000;
    case 921600:
      return B921600;
    default:
      return MakeError(ErrorCode::kBadInput, fmt::format("unsupported baud rate {}", baud));
  }
}

Expected<void> ServeRtu(SimulatedDrive& drive, const SimServerOptions& options,
                        std::stop_token stop,
                        const std::function<void(const std::string&)>& on_ready) {
  auto log = Logger("turntable");
  UniqueFd fd(::open(options.device.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC));
  if (!fd.valid()) {
    return MakeError(errno == ENOENT ? ErrorCode::kNotFound : ErrorCode::kIo,
                     fmt::format("cannot open {}: {}", options.device, std::strerror(errno)));
  }
  Expected<speed_t> speed = BaudConstant(options.baud);
  if (!speed) return std::unexpected(speed.error());
  termios tio{};
  if (::tcgetattr(fd.get(), &tio) == 0) {
    ::cfmakeraw(&tio);
    ::cfsetispeed(&tio, *speed);
    ::cfsetospeed(&tio, *speed);
    tio.c_cflag |= CLOCAL | CREAD;
    tio.c_cflag &= ~static_cast<tcflag_t>(CSIZE | PARENB | PARODD | CSTOPB);
    tio.c_cflag |= options.data_bits == 7 ? CS7 : CS8;
    if (options.parity != 'N') tio.c_cflag |= PARENB;
    if (options.parity == 'O') tio.c_cflag |= PARODD;
    if (options.stop_bits == 2) tio.c_cflag |= CSTOPB;
    tio.c_cc[VMIN] = 0;
    tio.c_cc[VTIME] = 0;
    ::tcsetattr(fd.get(), TCSANOW, &tio);
  }
  ::tcflush(fd.get(), TCIOFLUSH);
  on_ready(fmt::format("listening on rtu {} {} {}{}{} slave {}", options.device, options.baud,
                       options.data_bits, options.parity, options.stop_bits, options.slave_id));

  // A frame ends after 3.5 characters of silence; on a pty bytes arrive in bursts, so a longer
  // gap only serves to drop the remains of a broken frame.
  const auto kStaleGap = std::chrono::milliseconds(50);
  std::vector<std::uint8_t> buffer;
  SteadyClock::time_point last_byte = SteadyClock::now();
  while (!stop.stop_requested()) {
    pollfd p{fd.get(), POLLIN, 0};
    const int ready = ::poll(&p, 1, 20);
    const auto now = SteadyClock::now();
    if (ready > 0 && (p.revents & POLLIN) != 0) {
      std::uint8_t chunk[512];
      const ssize_t n = ::read(fd.get(), chunk, sizeof chunk);
      if (n > 0) {
        buffer.insert(buffer.end(), chunk, chunk + n);
        last_byte = now;
      }
    } else if (ready > 0 && (p.revents & (POLLHUP | POLLERR)) != 0) {
      // The other end of a pty pair is closed: wait for a new client.
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    (void)drive.LinkDown(now);  // let faults strike on time even without traffic
    while (!buffer.empty()) {
      const std::optional<std::size_t> length = RtuRequestLength(buffer);
      if (length && *length == 0) {
        log->debug("simulated drive: dropping {} bytes of an unknown function", buffer.size());
        buffer.clear();
        break;
      }
      if (!length || buffer.size() < *length) {
        if (now - last_byte > kStaleGap) {
          log->debug("simulated drive: dropping {} bytes of an incomplete frame", buffer.size());
          buffer.clear();
        }
        break;
      }
      const std::vector<std::uint8_t> frame(buffer.begin(),
                                            buffer.begin() + static_cast<std::ptrdiff_t>(*length));
      buffer.erase(buffer.begin(), buffer.begin() + static_cast<std::ptrdiff_t>(*length));
      const std::uint16_t crc =
          static_cast<std::uint16_t>(frame[frame.size() - 2] | frame[frame.size() - 1] << 8);
      if (Crc16(std::span(frame).first(frame.size() - 2)) != crc) {
        log->info("simulated drive: request with a bad CRC ignored: {}", ToHex(frame));
        buffer.clear();
        break;
      }
      const std::uint8_t slave = frame[0];
      if (slave != options.slave_id && slave != 0) continue;
      SimReply reply = drive.Handle(std::span(frame).subspan(1, frame.size() - 3), now);
      if (slave == 0 || reply.action == SimReply::Action::kDrop) continue;
      std::vector<std::uint8_t> adu = EncodeRtuAdu(slave, reply.pdu);
      if (reply.action == SimReply::Action::kCorrupt) adu.back() ^= 0x5A;
      if (!WriteAll(fd.get(), adu)) {
        return MakeError(ErrorCode::kIo,
                         fmt::format("writing to {}: {}", options.device, std::strerror(errno)));
      }
    }
  }
  return {};
}

}  // namespace

Expected<void> RunSimServer(SimulatedDrive& drive, const SimServerOptions& options,
                            std::stop_token stop,
                            const std::function<void(const std::string&)>& on_ready) {
  if (options.transport == SimServerOptions::Transport::kTcp) {
    return ServeTcp(drive, options, stop, on_ready);
  }
  return ServeRtu(drive, options, stop, on_ready);
}

}  // namespace revolve::turntable::modbus
