#include "capture/v4l2/v4l2_sys.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>

#if REVOLVE_HAVE_LIBV4L2
#include <libv4l2.h>
#endif

namespace revolve::capture {
namespace {

int PollOne(int fd, short events, int timeout_ms, short* revents) {
  pollfd p{fd, events, 0};
  int r;
  do {
    r = ::poll(&p, 1, timeout_ms);
  } while (r < 0 && errno == EINTR);
  if (r < 0) return -errno;
  *revents = p.revents;
  return r;
}

class KernelV4l2Sys final : public V4l2Sys {
 public:
  int Open(const std::string& path, int flags) override {
    const int fd = ::open(path.c_str(), flags);
    return fd < 0 ? -errno : fd;
  }
  int Close(int fd) override { return ::close(fd) < 0 ? -errno : 0; }
  int Ioctl(int fd, unsigned long request, void* arg) override {
    int r;
    do {
      r = ::ioctl(fd, request, arg);
    } while (r < 0 && errno == EINTR);
    return r < 0 ? -errno : r;
  }
  void* Mmap(std::size_t length, int fd, std::int64_t offset, int* error) override {
    void* p = ::mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, fd, offset);
    if (p == MAP_FAILED) {
      *error = errno;
      return nullptr;
    }
    return p;
  }
  int Munmap(void* address, std::size_t length) override {
    return ::munmap(address, length) < 0 ? -errno : 0;
  }
  int Poll(int fd, short events, int timeout_ms, short* revents) override {
    return PollOne(fd, events, timeout_ms, revents);
  }
};

#if REVOLVE_HAVE_LIBV4L2
class LibV4l2Sys final : public V4l2Sys {
 public:
  int Open(const std::string& path, int flags) override {
    const int fd = ::v4l2_open(path.c_str(), flags);
    return fd < 0 ? -errno : fd;
  }
  int Close(int fd) override { return ::v4l2_close(fd) < 0 ? -errno : 0; }
  int Ioctl(int fd, unsigned long request, void* arg) override {
    int r;
    do {
      r = ::v4l2_ioctl(fd, request, arg);
    } while (r < 0 && errno == EINTR);
    return r < 0 ? -errno : r;
  }
  void* Mmap(std::size_t length, int fd, std::int64_t offset, int* error) override {
    void* p = ::v4l2_mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, fd, offset);
    if (p == MAP_FAILED) {
      *error = errno;
      return nullptr;
    }
    return p;
  }
  int Munmap(void* address, std::size_t length) override {
    return ::v4l2_munmap(address, length) < 0 ? -errno : 0;
  }
  int Poll(int fd, short events, int timeout_ms, short* revents) override {
    return PollOne(fd, events, timeout_ms, revents);
  }
};
#endif

}  // namespace

std::unique_ptr<V4l2Sys> MakeKernelV4l2Sys() { return std::make_unique<KernelV4l2Sys>(); }

std::unique_ptr<V4l2Sys> MakeLibV4l2Sys() {
#if REVOLVE_HAVE_LIBV4L2
  return std::make_unique<LibV4l2Sys>();
#else
  return nullptr;
#endif
}

}  // namespace revolve::capture
