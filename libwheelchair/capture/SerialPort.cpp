#include "libwheelchair/capture/SerialPort.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>
#include <cerrno>
#include <cstring>

namespace wheelchair::capture {

long SerialPort::speedConstant(int baud) {
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
    case 1000000:
      return B1000000;
    case 2000000:
      return B2000000;
    default:
      return -1;
  }
}

bool SerialPort::open(const std::string& path, int baud, std::string& error) {
  close();
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    error = "open " + path + ": " + std::strerror(errno);
    return false;
  }
  if (isatty(fd)) {
    termios tio{};
    if (tcgetattr(fd, &tio) != 0) {
      error = "tcgetattr " + path + ": " + std::strerror(errno);
      ::close(fd);
      return false;
    }
    cfmakeraw(&tio);
    tio.c_cflag |= CLOCAL | CREAD;
    tio.c_cflag &= ~(CSTOPB | PARENB | CRTSCTS);
    tio.c_cc[VMIN] = 0;
    tio.c_cc[VTIME] = 0;
    if (baud > 0) {
      const long sp = speedConstant(baud);
      if (sp < 0) {
        error = "unsupported baud rate " + std::to_string(baud);
        ::close(fd);
        return false;
      }
      cfsetispeed(&tio, static_cast<speed_t>(sp));
      cfsetospeed(&tio, static_cast<speed_t>(sp));
    }
    // TCSANOW, not TCSAFLUSH: lines already waiting in the driver are kept.
    if (tcsetattr(fd, TCSANOW, &tio) != 0) {
      error = "tcsetattr " + path + ": " + std::strerror(errno);
      ::close(fd);
      return false;
    }
    ioctl(fd, TIOCEXCL);  // no second reader on the same device
  }
  fd_ = fd;
  return true;
}

void SerialPort::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

SerialPort::ReadResult SerialPort::read(char* buf, std::size_t cap, std::size_t& n,
                                        double timeout_s, std::string& error) {
  n = 0;
  if (fd_ < 0) {
    error = "not open";
    return ReadResult::HangUp;
  }
  pollfd p{fd_, POLLIN, 0};
  const int rc = ::poll(&p, 1, static_cast<int>(timeout_s * 1000));
  if (rc < 0) {
    if (errno == EINTR) return ReadResult::Timeout;
    error = std::string("poll: ") + std::strerror(errno);
    return ReadResult::HangUp;
  }
  if (rc == 0) return ReadResult::Timeout;
  if (p.revents & POLLNVAL) {
    error = "device closed";
    return ReadResult::HangUp;
  }
  const ssize_t k = ::read(fd_, buf, cap);
  if (k > 0) {
    n = static_cast<std::size_t>(k);
    return ReadResult::Data;
  }
  if (k == 0) {
    // EOF: pty master closed, FIFO writer gone, device hung up.
    error = "end of file (device hung up)";
    return ReadResult::HangUp;
  }
  if (errno == EAGAIN || errno == EINTR) {
    if (p.revents & (POLLHUP | POLLERR)) {
      error = "device hung up";
      return ReadResult::HangUp;
    }
    return ReadResult::Timeout;
  }
  error = std::string("read: ") + std::strerror(errno);  // EIO/ENODEV when unplugged
  return ReadResult::HangUp;
}

}  // namespace wheelchair::capture
