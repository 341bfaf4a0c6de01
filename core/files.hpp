#pragma once
/// Files written whole or not at all, and durably: outputs, reports and checkpoints are written
/// to a temporary file beside their place, synced to the disk, renamed into it, and the folder is
/// synced, so a crash or a power cut leaves the old file or the new one, never half of one.
#include <filesystem>
#include <string>
#include <vector>

namespace scout::core {

/// A fresh hidden name beside `file` (".NAME.tmp-PID-XXXXXXXX"), for writing before a rename; it
/// never names a file of the user's. The writer's process id in the name lets a later write tell
/// a temporary that a killed process left behind from one that is still being written.
std::filesystem::path temporary_path_beside(const std::filesystem::path& file);

/// A hidden name for `purpose` beside `target`: ".NAME.PURPOSE-PID-XXXXXXXX" (e.g. a staging
/// folder ".out.partial-PID-XXXXXXXX").
std::filesystem::path stamped_path_beside(const std::filesystem::path& target, const std::string& purpose);

/// Removes what killed processes left beside `target`: the entries of its folder named
/// ".NAME.PURPOSE-PID-..." (as stamped_path_beside makes them) whose process no longer runs on
/// this machine. Entries of running processes, and anything else, are never touched. Returns how
/// many were removed; errors are ignored (a later run tries again).
int remove_stale_beside(const std::filesystem::path& target, const std::string& purpose);

/// The same for entries of `folder` named "PREFIX-PID-..." (e.g. ".npm-tmp-PID-XXXXXX").
int remove_stale_in(const std::filesystem::path& folder, const std::string& prefix);

/// The entries of `folder` named "PREFIX-PID-..." whose process no longer runs, oldest first.
std::vector<std::filesystem::path> stale_entries(const std::filesystem::path& folder, const std::string& prefix);

/// Writes `text` to `file` atomically and durably. Throws InputError ("FILE: cannot write (No
/// space left on device)") and leaves the previous file and no temporary file behind.
void write_file_atomic(const std::filesystem::path& file, const std::string& text);

/// Moves a finished `temporary` (written beside `file`) into place durably: syncs its data,
/// renames it over `file`, then syncs the folder so the rename itself survives a power cut.
/// Throws InputError naming `file`; the temporary is removed on failure and `file` is unchanged.
void commit_file(const std::filesystem::path& temporary, const std::filesystem::path& file);

/// Syncs a folder's entries (after files were created, renamed or removed in it). Throws
/// InputError naming it.
void sync_directory(const std::filesystem::path& folder);

}  // namespace scout::core
