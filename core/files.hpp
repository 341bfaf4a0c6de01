#pragma once
/// Files written whole or not at all, and durably: outputs, reports and checkpoints are written
/// to a temporary file beside their place, synced to the disk, renamed into it, and the folder is
/// synced, so a crash or a power cut leaves the old file or the new one, never half of one.
#include <filesystem>
#include <string>

namespace scout::core {

/// A fresh hidden name beside `file` (".NAME.tmp-XXXXXXXX"), for writing before a rename; it never
/// names a file of the user's.
std::filesystem::path temporary_path_beside(const std::filesystem::path& file);

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
