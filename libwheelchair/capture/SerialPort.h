// A serial port read through POSIX termios (raw mode, non-blocking, poll()), used by every
// text source of `wheelchair capture`. Works for USB-serial adapters (/dev/ttyUSB*,
// /dev/ttyACM*), /dev/serial/by-id links, pseudo-terminals (the replay) and FIFOs.
//
// Why not mrpt::comms::CSerialPort: it polls FIONREAD with 1 ms sleeps and does not report a
// hang-up (unplugged USB adapter, closed pty master) as such, so a source could not tell an
// unplugged device from a quiet one. Here a hang-up is a distinct result (docs/capture.md).
#pragma once

#include <cstddef>
#include <string>

namespace wheelchair::capture {

class SerialPort {
 public:
  enum class ReadResult { Data, Timeout, HangUp };

  SerialPort() = default;
  ~SerialPort() { close(); }
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;

  /// Opens `path` (following symlinks) and, for a tty, sets raw 8N1 at `baud` (0 = keep).
  /// Returns false with `error` set ("open /dev/ttyUSB0: No such file or directory").
  bool open(const std::string& path, int baud, std::string& error);
  void close();
  bool isOpen() const { return fd_ >= 0; }

  /// Waits up to timeout_s for data; reads what is available into buf (at most cap bytes).
  ReadResult read(char* buf, std::size_t cap, std::size_t& n, double timeout_s, std::string& error);

  /// termios speed constant for a baud rate; -1 if unsupported.
  static long speedConstant(int baud);

 private:
  int fd_ = -1;
};

}  // namespace wheelchair::capture
