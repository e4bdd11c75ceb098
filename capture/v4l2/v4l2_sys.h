// The seam under the V4L2 backend: the six system calls it makes. The kernel implementation
// forwards to libc (or libv4l2); tests substitute a fake that emulates a device.
//
// Every call returns a non-negative value on success and -errno on failure (errno itself is
// never read by callers), so a fake needs no thread-local state.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace revolve::capture {

class V4l2Sys {
 public:
  virtual ~V4l2Sys() = default;

  // open(path, flags): a file descriptor or -errno.
  virtual int Open(const std::string& path, int flags) = 0;
  virtual int Close(int fd) = 0;
  // ioctl(fd, request, arg), retried on EINTR: >= 0 or -errno.
  virtual int Ioctl(int fd, unsigned long request, void* arg) = 0;
  // mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, fd, offset): the address, or
  // nullptr with *error = errno.
  virtual void* Mmap(std::size_t length, int fd, std::int64_t offset, int* error) = 0;
  virtual int Munmap(void* address, std::size_t length) = 0;
  // poll() on one fd: the number of ready fds (0 on timeout) with *revents set, or -errno.
  virtual int Poll(int fd, short events, int timeout_ms, short* revents) = 0;
};

// Raw system calls.
std::unique_ptr<V4l2Sys> MakeKernelV4l2Sys();

// Through libv4l2 (v4l2_open, v4l2_ioctl, ...: format emulation for cameras with odd formats);
// nullptr when this build has no libv4l2.
std::unique_ptr<V4l2Sys> MakeLibV4l2Sys();

}  // namespace revolve::capture
