#pragma once
/// What `--precision auto` means: the arithmetic (fp32 or bf16) in which Scout's networks train
/// and evaluate faster on this CPU with this LibTorch. Torch-free.
///
/// Native bf16 (AMX-BF16 or AVX-512 BF16, agent::native_bf16()) is necessary but not sufficient:
/// on a 2-core Intel Xeon with AVX-512 BF16 (AMX hidden by its virtual machine) bf16 trained mode
/// (iii) 27 % slower than fp32, while on an AMD EPYC it was 2.6-2.9x faster. So where bf16 is
/// native, both are measured once (a training step of the default networks, about a second) and
/// the choice is cached per CPU model, instruction-set cap and LibTorch version.
#include <filesystem>
#include <string>

#include "agent/config.hpp"

namespace scout::learn {

struct PrecisionChoice {
  agent::Precision precision = agent::Precision::Float32;  ///< Float32 or BFloat16, never Auto
  /// One line for the user: "precision: bf16 (measured on this CPU with LibTorch 2.15.0: a
  /// training step in 41 ms against 103 ms in fp32; cached in ...)".
  std::string note;
};

/// `requested` unchanged, except Auto -> auto_precision().precision.
agent::Precision resolve_precision(agent::Precision requested);

/// Auto's choice and why. Without native bf16: fp32, measuring nothing. With it: the cached choice
/// for this CPU, or a new measurement (written to the cache; a process that finds another one
/// measuring waits for its result, so runs started together agree). bf16 is chosen only where its
/// step is at least 10 % faster: within that, fp32's exact arithmetic wins. Remembered for the
/// life of the process.
PrecisionChoice auto_precision();

/// The cache file: $SCOUT_CACHE_DIR/precision.json, else $XDG_CACHE_HOME/scout/precision.json,
/// else ~/.cache/scout/precision.json.
std::filesystem::path precision_cache_file();

}  // namespace scout::learn
