#pragma once
//! \file
//! Whole-file reads and atomic writes (temporary file in the same folder, then rename), so a
//! crash or an error never leaves a half-written file under the final name.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace zipfusion {

//! Throws IoError naming the file when it cannot be opened or read (no such file, not a regular
//! file, a read error).
std::vector<std::uint8_t> read_file_bytes(const std::filesystem::path& path);
//! The same into `bytes`, whose buffer is reused: once it has grown to the largest file read,
//! reading allocates nothing (the frames of a capture, frame set after frame set).
void read_file_bytes(const std::string& path, std::vector<std::uint8_t>& bytes);

//! Writes bytes to path atomically. Throws IoError naming the file on failure.
void write_file_atomic(const std::filesystem::path& path, std::span<const std::uint8_t> bytes);
void write_file_atomic(const std::filesystem::path& path, std::string_view text);

//! Throws IoError naming `path` when a file could not be written there: its folder does not exist,
//! is not writable or takes no new file (a probe file is made there and removed), or the path is
//! a folder. For commands that compute for a while before
//! they write one file, checked first so that the work is not lost.
void check_output_file(const std::filesystem::path& path);

//! Throws IoError "`path`: not `what` (a file, not a folder)", or "(no such folder)", unless
//! `path` is a folder: what an input folder that is not there gets.
void check_input_folder(const std::filesystem::path& path, std::string_view what);

//! The folder a path names, without trailing separators or "." components: "out/" and "out/." are
//! "out"; "." and "/" stay.
std::filesystem::path folder_path(const std::filesystem::path& dir);

//! The folder to write for an output folder asked for as `dir`: folder_path(dir), then any chain
//! of links followed to where it ends, dangling or not, so that a link to the folder stays a link
//! and is not replaced by the folder written. Throws InvalidInput on a loop of links.
std::filesystem::path output_folder(const std::filesystem::path& dir);

//! Throws InvalidInput when `dir` exists and is not an empty folder (`option` names the command
//! line option that chose it), and IoError when a file stands where its parent folders would be
//! made. Nothing is created (write_folder_atomic makes the parents). A link is followed: what is
//! checked (and written by write_folder_atomic) is the folder it points to.
void check_new_folder(const std::filesystem::path& dir, std::string_view option);

//! Writes a whole folder atomically: `fill` writes into a hidden staging folder beside `dir`
//! (".NAME.partial-PID", its parent folders made as needed), which is then renamed to `dir` (which
//! check_new_folder accepted). On any error the staging folder and the parents this call made are
//! removed and the error rethrown (a filesystem error as IoError naming the path). Staging folders
//! of earlier runs whose process is gone (killed) are removed first.
void write_folder_atomic(const std::filesystem::path& dir, const std::function<void(const std::filesystem::path& staging)>& fill);

//! This machine's host name ("localhost" where it has none): staging folders and URLs name it.
std::string host_name();

//! Files that appear in a folder together, or not at all: a run writes them into staging(), a
//! hidden folder inside it, and commit() moves them in, replacing files of the same names. A run
//! that fails, or that ends without commit(), leaves the folder as it found it. The folder is
//! locked meanwhile (flock: visible to every process, dropped by the kernel when the process
//! dies), so two runs cannot mix their files.
class StagedFolder {
 public:
  //! Makes `dir` (a link followed, as output_folder does) and its parents where missing, and locks
  //! it. Throws InvalidInput when another run holds it (`option` names the command-line option
  //! that chose it) and IoError when it cannot be made. The staging folders of killed runs on this
  //! machine (their PID names no process) are removed: removed() lists them.
  StagedFolder(const std::filesystem::path& dir, std::string_view option);
  //! Without commit(): removes the staging folder, then `dir` and the parents this made if empty.
  ~StagedFolder();
  StagedFolder(const StagedFolder&) = delete;
  StagedFolder& operator=(const StagedFolder&) = delete;

  const std::filesystem::path& dir() const { return dir_; }
  const std::filesystem::path& staging() const { return staging_; }
  bool made_dir() const { return made_dir_; }
  const std::vector<std::filesystem::path>& removed() const { return removed_; }

  //! `text` (an error's) with the staging folder's path replaced by the folder's.
  std::string in_user_terms(std::string text) const;

  //! Moves every file of staging() into dir(), the one named `last` after all others (so that it
  //! appearing means the rest are there; an earlier one of that name is removed first), then
  //! removes staging(). Throws IoError naming the file, and that the folder is partly updated.
  void commit(const std::string& last = {});

 private:
  std::filesystem::path dir_, staging_, existing_;  // existing_: the nearest folder above dir_ that existed
  bool made_dir_ = false;
  bool committed_ = false;
  int lock_fd_ = -1;
  std::vector<std::filesystem::path> removed_;
};

}  // namespace zipfusion
