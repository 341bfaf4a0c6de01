#pragma once
/// Files written whole or not at all: outputs, reports and checkpoints are written to a
/// temporary file beside their place and renamed into it, so a crash never leaves half a file.
#include <filesystem>
#include <string>

namespace scout::core {

/// A fresh hidden name beside `file` (".NAME.tmp-XXXXXXXX"), for writing before a rename; it never
/// names a file of the user's.
std::filesystem::path temporary_path_beside(const std::filesystem::path& file);

/// Writes `text` to `file` atomically. Throws InputError ("FILE: cannot write (...)") and leaves
/// no temporary file behind.
void write_file_atomic(const std::filesystem::path& file, const std::string& text);

}  // namespace scout::core
