#pragma once
// Message digests of files: SHA-256 for data checksums and manifests, SHA-512 for npm's
// integrity strings, MD5 for the checksums MNIST's distribution publishes.
#include <cstdint>
#include <filesystem>
#include <vector>

namespace scout::core {

enum class DigestKind { Sha256, Sha512, Md5 };

/// The digest of a file's bytes. Throws InputError naming the file if it cannot be read.
std::vector<std::uint8_t> digest_file(const std::filesystem::path& file, DigestKind kind);

}  // namespace scout::core
