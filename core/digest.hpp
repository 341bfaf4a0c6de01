#pragma once
// Message digests of files: SHA-256 for data checksums and manifests, SHA-512 for npm's
// integrity strings, MD5 for the checksums MNIST's distribution publishes.
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace scout::core {

enum class DigestKind { Sha256, Sha512, Md5 };

/// The digest of a file's bytes. Throws InputError naming the file if it cannot be read.
std::vector<std::uint8_t> digest_file(const std::filesystem::path& file, DigestKind kind);

/// Bytes as lowercase hex, two digits each.
std::string to_hex(std::span<const std::uint8_t> bytes);

/// SHA-256 of a file, lowercase hex (manifests, data checks, a run's data digests).
std::string sha256_hex(const std::filesystem::path& file);

}  // namespace scout::core
