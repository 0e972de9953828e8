#include "zipfusion/io/file_util.h"

#include <algorithm>
#include <fstream>
#include <random>
#include <string>
#include <system_error>
#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "zipfusion/core/error.h"

namespace zipfusion {

std::vector<std::uint8_t> read_file_bytes(const std::filesystem::path& path) {
  std::vector<std::uint8_t> bytes;
  read_file_bytes(path.string(), bytes);
  return bytes;
}

void read_file_bytes(const std::string& path, std::vector<std::uint8_t>& bytes) {
  constexpr const char* kNotRegular = ": not a regular file (a folder, device or pipe)";
  // Nothing but a regular file is opened: opening a device can act (a tape rewinds, a watchdog
  // arms). The type is asked again of what was opened, in case the name changed in between; then
  // O_NONBLOCK keeps a pipe from making open wait for a writer, O_NOCTTY a terminal from becoming
  // ours. (errno is copied at once: building the message may change it.)
  struct stat status {};
  if (::stat(path.c_str(), &status) != 0) {
    const int error = errno;
    if (error == ENOENT || error == ENOTDIR) throw IoError(path + ": no such file");
    throw IoError(path + ": cannot open for reading: " + std::strerror(error));
  }
  if (!S_ISREG(status.st_mode)) throw IoError(path + kNotRegular);
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
  if (fd < 0) {
    const int error = errno;
    throw IoError(path + ": cannot open for reading: " + std::strerror(error));
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  if (::fstat(fd, &status) != 0) {
    const int error = errno;
    throw IoError(path + ": cannot determine size: " + std::strerror(error));
  }
  if (!S_ISREG(status.st_mode)) throw IoError(path + kNotRegular);
  const size_t size = static_cast<size_t>(status.st_size);
  // A buffer kept from a file far larger than this one (a bogus frame file) is not kept for ever.
  if (bytes.capacity() > 2 * size + (std::size_t{1} << 20)) std::vector<std::uint8_t>().swap(bytes);
  bytes.resize(size);
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t got = ::read(fd, bytes.data() + done, bytes.size() - done);
    const int error = errno;
    if (got < 0 && error == EINTR) continue;
    if (got < 0) throw IoError(path + ": read failed: " + std::strerror(error));
    if (got == 0) throw IoError(path + ": read failed (the file became shorter)");
    done += static_cast<size_t>(got);
  }
}

void write_file_atomic(const std::filesystem::path& given_path, std::span<const std::uint8_t> bytes) {
  namespace fs = std::filesystem;
  std::error_code ec;
  // Written through a symbolic link (the rename would replace the link itself), and never over a
  // device, pipe or folder (the rename replaced /dev/full, as root, with a regular file).
  // Followed link by link (weakly_canonical stops at a link whose target does not exist yet).
  fs::path path = given_path;
  for (int hops = 0; fs::is_symlink(fs::symlink_status(path, ec)); ++hops) {
    const fs::path target = fs::read_symlink(path, ec);
    if (ec || hops == 40) throw IoError(given_path.string() + ": cannot follow the link" + (ec ? ": " + ec.message() : std::string(" (a loop?)")));
    path = target.is_absolute() ? target : path.parent_path() / target;
  }
  if (const fs::file_status status = fs::status(path, ec); fs::exists(status) && !fs::is_regular_file(status)) {
    throw IoError(given_path.string() + ": not a regular file (a folder, device or pipe), not replaced");
  }
  // A unique suffix keeps two writers of the same file from sharing a temporary.
  thread_local std::mt19937_64 rng{std::random_device{}()};
  std::filesystem::path tmp = path;
  tmp += ".tmp" + std::to_string(rng() % 1000000000ULL);
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw IoError(path.string() + ": cannot open for writing");
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    out.flush();
    if (!out) {
      out.close();
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw IoError(path.string() + ": write failed");
    }
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw IoError(path.string() + ": cannot rename temporary file: " + ec.message());
  }
}

void write_file_atomic(const std::filesystem::path& path, std::string_view text) {
  write_file_atomic(path, std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

void check_input_folder(const std::filesystem::path& path, std::string_view what) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_directory(path, ec)) return;
  throw IoError(path.string() + ": not " + std::string(what) + " (" + (fs::exists(path, ec) ? "a file, not a folder" : "no such folder") + ")");
}

void check_output_file(const std::filesystem::path& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw InvalidInput(path.string() + ": is a folder, not a file to write");
  const fs::path folder = path.has_parent_path() ? path.parent_path() : fs::path(".");
  if (!fs::is_directory(folder, ec)) throw IoError(path.string() + ": cannot write: folder " + folder.string() + " does not exist");
  if (::access(folder.c_str(), W_OK) != 0) throw IoError(path.string() + ": cannot write: folder " + folder.string() + " is not writable");
  // The folder's permissions do not tell everything (/proc, a read-only mount, a full disk's
  // inodes): a file is made there, as write_file_atomic's temporary will be, and removed.
  const fs::path probe = folder / (".zf_write_probe_" + std::to_string(::getpid()));
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0600);
  if (fd < 0) {
    const int error = errno;
    // The folder exists (checked above), so ENOENT here is a file system that makes no files
    // (/proc answered "No such file or directory", which named the folder as missing).
    if (error == ENOENT) throw IoError(path.string() + ": cannot write: folder " + folder.string() + " does not take new files");
    if (error != EEXIST) throw IoError(path.string() + ": cannot write: folder " + folder.string() + ": " + std::strerror(error));
    return;  // another check of this process made it: the folder takes files
  }
  ::close(fd);
  ::unlink(probe.c_str());
}

std::filesystem::path folder_path(const std::filesystem::path& dir) {
  // Only trailing separators and "." go: "a/../b" is left to the OS, which resolves ".." through
  // a link where a lexical normalisation would not.
  std::filesystem::path folder = dir;
  while (folder.has_relative_path() && (!folder.has_filename() || folder.filename() == ".")) {
    const std::filesystem::path parent = folder.parent_path();
    if (parent.empty()) break;  // "." itself
    folder = parent;
  }
  return folder;
}

std::filesystem::path output_folder(const std::filesystem::path& asked_for) {
  namespace fs = std::filesystem;
  fs::path dir = folder_path(asked_for);
  std::error_code ec;
  for (int hops = 0; fs::is_symlink(dir, ec); ++hops) {
    if (hops == 40) throw InvalidInput(asked_for.string() + ": a loop of links");  // Linux's own limit
    const fs::path target = fs::read_symlink(dir, ec);
    if (ec) throw IoError(dir.string() + ": cannot read the link: " + ec.message());
    dir = folder_path(target.is_absolute() ? target : dir.parent_path() / target);
  }
  return dir;
}

namespace {

// `path` if it exists, else the nearest folder above it that does ("." above a relative path's
// first folder): where making `path`'s missing folders starts.
std::filesystem::path nearest_existing(std::filesystem::path path) {
  std::error_code ec;
  while (!std::filesystem::exists(path, ec)) {
    if (!path.has_parent_path() || path == path.parent_path()) return path.is_absolute() ? path : std::filesystem::path(".");
    path = path.parent_path();
  }
  return path;
}

}  // namespace

void check_new_folder(const std::filesystem::path& asked_for, std::string_view option) {
  namespace fs = std::filesystem;
  const fs::path dir = output_folder(asked_for);
  // Named as asked for, and where a link leads, by both.
  const std::string name = dir == folder_path(asked_for) ? dir.string() : asked_for.string() + " (a link to " + dir.string() + ")";
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) {
    throw InvalidInput(name + ": is a file, not a folder (choose a new " + std::string(option) + ")");
  }
  if (fs::exists(dir, ec) && !fs::is_empty(dir, ec)) {
    throw InvalidInput(name + ": already exists and is not empty (choose a new " + std::string(option) + ")");
  }
  // The parent is made by the writing, not here: a run that fails before it (a subject file
  // missing) leaves no empty folders behind. Here only nothing may stand in its way.
  const fs::path existing = nearest_existing(dir.has_parent_path() ? dir.parent_path() : fs::path("."));
  if (fs::exists(existing, ec) && !fs::is_directory(existing, ec)) {
    throw IoError(existing.string() + ": is a file, so the output's parent folder cannot be made there");
  }
}

namespace {

// An error's text with the hidden staging folder's path replaced by the folder the user asked for.
std::string in_folder_asked_for(std::string text, const std::filesystem::path& staging, const std::filesystem::path& dir) {
  const std::string from = staging.string(), to = dir.string();
  for (size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size())) text.replace(at, from.size(), to);
  return text;
}

// The writing run holds an exclusive flock on its staging folder until the rename: a lock any
// process on the machine (in any PID namespace) can see, and that the kernel drops when the
// process dies. Returns the descriptor to close afterwards, or -1.
int lock_staging(const std::filesystem::path& staging) {
  const int fd = ::open(staging.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0 && ::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// A killed run (SIGKILL, a power cut) leaves its staging folder, PREFIX + PID (".NAME.partial-PID"
// beside a folder write_folder_atomic writes, ".zipfusion-staging-HOST-PID" in a StagedFolder),
// and no later run has its PID. Such a folder in `parent` is removed before a new one is made
// when no process holds its lock and its PID names no process here (a run in another PID
// namespace holds the lock). Returns the folders removed.
std::vector<std::filesystem::path> remove_abandoned_staging(const std::filesystem::path& parent, const std::string& prefix) {
  namespace fs = std::filesystem;
  std::error_code ec;
  std::vector<fs::path> removed;
  for (const fs::directory_entry& entry : fs::directory_iterator(parent, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string pid_text = name.substr(prefix.size());
    if (!std::all_of(pid_text.begin(), pid_text.end(), [](char c) { return c >= '0' && c <= '9'; }) || pid_text.size() > 9) continue;
    const pid_t pid = static_cast<pid_t>(std::stol(pid_text));
    if (pid == ::getpid() || ::kill(pid, 0) == 0 || errno != ESRCH) continue;  // alive, or not ours to judge
    const int lock = lock_staging(entry.path());
    if (lock < 0) continue;  // held: a run is writing it
    fs::remove_all(entry.path(), ec);
    ::close(lock);
    removed.push_back(entry.path());
  }
  return removed;
}

// Removes `from` and the folders above it up to `existing` (not included) while they are empty:
// those a failed run made.
void remove_empty_folders(const std::filesystem::path& from, const std::filesystem::path& existing) {
  std::error_code ec;
  for (std::filesystem::path p = from; !p.empty() && p != existing; p = p.parent_path()) {
    if (!std::filesystem::remove(p, ec)) break;  // remove() takes only an empty folder
  }
}

}  // namespace

void write_folder_atomic(const std::filesystem::path& asked_for, const std::function<void(const std::filesystem::path& staging)>& fill) {
  namespace fs = std::filesystem;
  const fs::path dir = output_folder(asked_for);  // the staging folder goes beside it, not into it
  const fs::path parent = dir.has_parent_path() ? dir.parent_path() : fs::path(".");
  // Appended piece by piece: GCC 12 warns (-Wrestrict, falsely) on "." + string + … once inlined here.
  std::string staging_prefix = ".";
  staging_prefix += dir.filename().string();
  staging_prefix += ".partial-";
  const fs::path staging = parent / (staging_prefix + std::to_string(::getpid()));
  std::error_code ec;
  remove_abandoned_staging(parent, staging_prefix);
  fs::remove_all(staging, ec);
  // The folders this call makes above the staging folder (those below `existing`), removed again
  // if it fails.
  const fs::path existing = nearest_existing(parent);
  auto clean_up = [&] {
    fs::remove_all(staging, ec);
    remove_empty_folders(parent, existing);
  };
  int lock = -1;
  struct Unlock {
    int& fd;
    ~Unlock() {
      if (fd >= 0) ::close(fd);
    }
  } unlock{lock};
  try {
    fs::create_directories(staging);
    lock = lock_staging(staging);
    fill(staging);
    if (fs::exists(dir, ec)) fs::remove(dir);  // an empty folder: check_new_folder allowed it
    fs::rename(staging, dir);
  } catch (const fs::filesystem_error& e) {
    clean_up();
    throw IoError(in_folder_asked_for(e.path1().string(), staging, dir) + ": cannot write (" + e.code().message() + ")");
  } catch (const IoError& e) {
    clean_up();
    throw IoError(in_folder_asked_for(e.what(), staging, dir));
  } catch (const InvalidInput& e) {
    clean_up();
    throw InvalidInput(in_folder_asked_for(e.what(), staging, dir));
  } catch (...) {
    clean_up();
    throw;
  }
}

std::string host_name() {
  char name[256] = {};
  if (::gethostname(name, sizeof name - 1) != 0 || name[0] == '\0') return "localhost";
  return name;
}

namespace {

// Every run's staging folder inside a StagedFolder's folder starts so, then names its host and PID.
constexpr std::string_view kStagingPrefix = ".zipfusion-staging-";

}  // namespace

StagedFolder::StagedFolder(const std::filesystem::path& asked_for, std::string_view option) : dir_(output_folder(asked_for)) {
  namespace fs = std::filesystem;
  std::error_code ec, made;
  existing_ = nearest_existing(dir_);
  made_dir_ = !fs::exists(dir_, ec);
  if (fs::exists(dir_, ec) && !fs::is_directory(dir_, ec)) throw InvalidInput(dir_.string() + ": is a file, not a folder (choose another " + std::string(option) + ")");
  fs::create_directories(dir_, made);
  if (!fs::is_directory(dir_, ec)) {
    // ENOENT under a folder that exists is a file system that makes no folders (/proc).
    const bool takes_none = made == std::errc::no_such_file_or_directory && fs::is_directory(existing_, ec);
    throw IoError(dir_.string() + ": cannot create output folder" +
                  (takes_none ? " (" + existing_.string() + " does not take new folders)" : made ? " (" + made.message() + ")" : std::string()));
  }
  lock_fd_ = ::open(dir_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (lock_fd_ < 0) throw IoError(dir_.string() + ": cannot open the output folder (" + std::strerror(errno) + ")");
  if (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    ::close(lock_fd_);
    lock_fd_ = -1;
    if (error == EWOULDBLOCK) {
      throw InvalidInput(dir_.string() + ": another zipfusion run is writing into this folder (choose another " + std::string(option) + " or wait for it)");
    }
    throw IoError(dir_.string() + ": cannot lock the output folder (" + std::strerror(error) + ")");
  }
  // A staging folder of this machine whose process is gone is a killed run's. flock does not
  // reach across machines on every network filesystem, so another machine's are left alone.
  std::string host = host_name();
  std::replace(host.begin(), host.end(), '/', '_');  // Linux lets a host name hold any byte
  const std::string ours = std::string(kStagingPrefix) + host + "-";
  removed_ = remove_abandoned_staging(dir_, ours);
  staging_ = dir_ / (ours + std::to_string(::getpid()));
  fs::remove_all(staging_, ec);
  if (!fs::create_directory(staging_, made)) {
    ::close(lock_fd_);
    lock_fd_ = -1;
    if (made_dir_) fs::remove(dir_, ec);
    throw IoError(dir_.string() + ": cannot write into the output folder (" + (made ? made.message() : std::string("exists")) + ")");
  }
}

StagedFolder::~StagedFolder() {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!committed_) {
    fs::remove_all(staging_, ec);
    if (made_dir_) remove_empty_folders(dir_, existing_);
  }
  if (lock_fd_ >= 0) ::close(lock_fd_);
}

std::string StagedFolder::in_user_terms(std::string text) const { return in_folder_asked_for(std::move(text), staging_, dir_); }

void StagedFolder::commit(const std::string& last) {
  namespace fs = std::filesystem;
  std::error_code ec;
  std::vector<fs::path> files;
  for (const fs::directory_entry& entry : fs::directory_iterator(staging_, ec)) files.push_back(entry.path().filename());
  if (ec) throw IoError(dir_.string() + ": cannot list the staged files (" + ec.message() + ")");
  std::sort(files.begin(), files.end());
  std::stable_partition(files.begin(), files.end(), [&](const fs::path& name) { return name.string() != last; });
  // An earlier `last` goes first: a folder a failed commit left half-updated then has none.
  if (!last.empty()) fs::remove(dir_ / last, ec);
  for (const fs::path& name : files) {
    fs::rename(staging_ / name, dir_ / name, ec);
    if (ec) throw IoError((dir_ / name).string() + ": cannot write (" + ec.message() + "); " + dir_.string() + " is partly updated");
  }
  committed_ = true;
  fs::remove(staging_, ec);
}

}  // namespace zipfusion
