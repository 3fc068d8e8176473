// Reading a user's file (URDF, robot.yaml, scenario, mesh, deployment): regular files only, at
// most a given size, and never a read that can block. A FIFO, a socket or a device named where a
// file is expected is refused at once with a message naming it (opening a FIFO for reading would
// wait for a writer forever; /dev/zero would never end).
#pragma once

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>

namespace poise::cli {

/// Thrown by read_regular_file; the message names the file kind, the path and the problem.
struct FileError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// The whole of the regular file `path`, at most `max_bytes`. `what` names the kind of file in
/// messages ("URDF", "scenario"). Throws FileError when the file is missing, is not a regular
/// file, cannot be read or is larger than the limit.
inline std::string read_regular_file(const std::filesystem::path& path, const std::string& what,
                                     std::size_t max_bytes) {
  std::string quoted(1, '\'');  // built by appending: GCC 12 warns (-Wrestrict) on "'" + s
  quoted += path.string();
  quoted += '\'';
  // O_NONBLOCK: opening a FIFO returns at once instead of waiting for a writer.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) {
    const int err = errno;
    if (err == ENOENT) throw FileError(what + " file not found: " + quoted);
    throw FileError("cannot open " + what + " file " + quoted + ": " + std::strerror(err));
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st{};
  if (::fstat(fd, &st) != 0)
    throw FileError("cannot read " + what + " file " + quoted + ": " + std::strerror(errno));
  if (S_ISDIR(st.st_mode))
    throw FileError(what + " path " + quoted + " is a directory, not a file");
  if (!S_ISREG(st.st_mode))
    throw FileError(what + " path " + quoted +
                    " is not a regular file (a FIFO, socket or device); refused");
  const auto limit_text = [&] {
    return what + " file " + quoted + " is larger than the limit of " + std::to_string(max_bytes) +
           " bytes (" + std::to_string(max_bytes >> 20) + " MB); refused";
  };
  if (static_cast<std::size_t>(st.st_size) > max_bytes) throw FileError(limit_text());
  std::string out;
  out.reserve(static_cast<std::size_t>(st.st_size));
  char buf[65536];
  for (;;) {
    const ssize_t got = ::read(fd, buf, sizeof buf);
    if (got < 0) {
      if (errno == EINTR) continue;
      throw FileError("error reading " + what + " file " + quoted + ": " + std::strerror(errno));
    }
    if (got == 0) break;
    if (out.size() + static_cast<std::size_t>(got) > max_bytes) throw FileError(limit_text());
    out.append(buf, static_cast<std::size_t>(got));
  }
  return out;
}

}  // namespace poise::cli
