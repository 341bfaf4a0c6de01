// Hostile checkpoint and model files: a seeded fuzz loop over random bytes and over Scout's own
// files with mutated bytes, header text, header fields, tensor bytes and configs. Every input is
// refused with one InputError line naming it, or accepted and loaded; none crashes, hangs or
// makes the process allocate far beyond the file (the peak resident size is checked). Mutations
// of the header are joined again with its length recomputed, so that they reach the checks behind
// the parser's.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "learn/internal/checkpoint.hpp"
#include "tests/support/safetensors_edit.hpp"
#include "tests/support/training_fixture.hpp"

namespace scout::learn {
namespace {

using namespace scout::learn::test_support;

using scout::testing::join;
using scout::testing::join_text;
using scout::testing::SafetensorsParts;
using scout::testing::split;

// What one mutated input may take beyond the largest of Scout's own files: the mutation can grow a
// record or a config within the bounds the reader allows, never to a network built from a bomb.
// AddressSanitizer's redzones and quarantine keep several times more resident.
#if defined(__SANITIZE_ADDRESS__)
constexpr long kInputSlackKiB = 4 * 32 * 1024;
#else
constexpr long kInputSlackKiB = 32 * 1024;
#endif

// --- The loop ------------------------------------------------------------------------------------

// A field of /proc/self/status, in KiB.
long status_kib(const std::string& field) {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind(field, 0) == 0) return std::stol(line.substr(field.size()));
  return -1;
}

// Resets the peak resident size (VmHWM) to the present one (writing 5 to /proc/self/clear_refs),
// so that each input's own peak is measured, not the process's lifetime peak; returns the
// present resident size.
long reset_peak_kib() {
  std::ofstream("/proc/self/clear_refs") << "5";
  return status_kib("VmRSS:");
}

struct Tally {
  int accepted = 0, refused = 0;
  long peak_kib = 0;  ///< the largest rise of the resident size while one input was read and loaded
};

// Feeds one input to open_checkpoint_bytes and loads its weights, as a resumed run does. Returns whether it was
// accepted; anything but a one-line InputError naming the input fails the test.
bool feed(const std::string& bytes, Tally& tally) {
  const std::string origin = "fuzz.safetensors";
  const long before = reset_peak_kib();
  struct Measure {
    long before;
    Tally& tally;
    ~Measure() { tally.peak_kib = std::max(tally.peak_kib, status_kib("VmHWM:") - before); }
  } measure{before, tally};
  try {
    const Checkpoint checkpoint = open_checkpoint_bytes(bytes, origin);
    agent::Agent agent(checkpoint.contents().state.config.network);
    checkpoint.contents().load_into(*agent, nullptr);
    ++tally.accepted;
    return true;
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(origin + ": ", 0), 0u) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    ++tally.refused;
    return false;
  }
}

class CheckpointFuzz : public Resume {
 protected:
  // A finished tiny run's checkpoint (weights, Adam's moments, the schedule) for `kind`.
  std::string checkpoint_of(agent::ClassifierKind kind, const std::string& name) {
    TrainConfig c = config({1, 0, 0});
    c.network.classifier = kind;
    c.network.classifier_width = kind == agent::ClassifierKind::ResNet18 ? 2 : 4;
    Trainer trainer(c, run_dir(name), kThreads);
    EXPECT_EQ(trainer.run({}).outcome, TrainOutcome::Finished);
    return read_bytes(temp_.path() / name / kCheckpointFile);
  }
};

// The fuzzer: a seeded generator, Scout's own files to mutate, and a tally per kind of input.
struct Fuzzer {
  std::mt19937_64 rng{20261207};
  std::vector<std::string> originals;  // three checkpoints and a model file
  std::map<std::string, Tally> tallies;

  std::size_t uniform(std::size_t n) { return static_cast<std::size_t>(rng() % n); }
  const std::string& original() { return originals[uniform(originals.size())]; }

  void random_bytes() {
    for (int i = 0; i < 1000; ++i) {
      std::string bytes(uniform(4096), '\0');
      for (char& c : bytes) c = static_cast<char>(rng());
      if (i % 2 && bytes.size() >= 8) {  // a header length that fits the file
        const std::string length = scout::testing::length_prefix(uniform(bytes.size() - 7));
        bytes.replace(0, 8, length);
      }
      EXPECT_FALSE(feed(bytes, tallies["random bytes"]));
    }
  }
  void raw_flips() {
    for (int i = 0; i < 1200; ++i) {
      std::string bytes = original();
      if (i % 6 == 0) {
        bytes.resize(uniform(bytes.size()));
        EXPECT_FALSE(feed(bytes, tallies["truncated"]));
        continue;
      }
      for (int k = 1 + uniform(3); k > 0; --k) bytes[uniform(bytes.size())] ^= static_cast<char>(1 + uniform(255));
      feed(bytes, tallies["raw flips"]);
    }
  }
  // The header's text: flipped, inserted, deleted or repeated bytes, joined with its new length.
  void header_text() {
    for (int i = 0; i < 1800; ++i) {
      const SafetensorsParts parts = split(original());
      std::string text = parts.header.dump();
      if (i % 3 == 0) {
        for (int k = 1 + uniform(3); k > 0; --k) text[uniform(text.size())] ^= static_cast<char>(1 + uniform(255));
      } else if (i % 3 == 1) {
        if (rng() % 2)
          text.insert(uniform(text.size()), 1, "{}[],:\"0123456789-e."[uniform(20)]);
        else
          text.erase(uniform(text.size()), 1);
      } else {
        const std::size_t from = uniform(text.size()), length = 1 + uniform(64);
        text.insert(uniform(text.size()), text.substr(from, length));
      }
      feed(join_text(text, parts.data), tallies["header text"]);
    }
  }
  // One tensor's dtype, shape or offsets set to another value.
  void header_fields() {
    const std::vector<nlohmann::ordered_json> values = {
        -1, 0, 1, 3, 255, 1u << 20, std::uint64_t{1} << 62, "F16", "BF16", "U8", "I32", "F64", nullptr, "", 1.5};
    for (int i = 0; i < 900; ++i) {
      SafetensorsParts parts = split(original());
      std::vector<std::string> names;
      for (const auto& [name, entry] : parts.header.items())
        if (name != "__metadata__") names.push_back(name);
      nlohmann::ordered_json& entry = parts.header[names[uniform(names.size())]];
      const nlohmann::ordered_json& value = values[uniform(values.size())];
      switch (uniform(4)) {
        case 0:
          entry["dtype"] = value;
          break;
        case 1:
          if (entry["shape"].empty()) entry["shape"] = {1};
          entry["shape"][uniform(entry["shape"].size())] = value;
          break;
        case 2:
          entry["data_offsets"][uniform(2)] = value;
          break;
        case 3:
          entry["shape"].push_back(value);
          break;
      }
      feed(join(parts), tallies["header fields"]);
    }
  }
  // The tensors' bytes: flipped, or the data shortened or grown.
  void tensor_bytes() {
    for (int i = 0; i < 600; ++i) {
      SafetensorsParts parts = split(original());
      if (i % 2) {
        for (int k = 1 + uniform(8); k > 0; --k)
          parts.data[uniform(parts.data.size())] ^= static_cast<char>(1 + uniform(255));
        feed(join(parts), tallies["tensor bytes"]);
      } else {
        if (rng() % 2)
          parts.data.resize(uniform(parts.data.size()));
        else
          parts.data += std::string(1 + uniform(64), '\0');
        EXPECT_FALSE(feed(join(parts), tallies["data length"]));
      }
    }
  }
  void configs() {
    const std::vector<std::string> fields = {"planner_width",    "planner_depth", "classifier_width",
                                             "classifier_depth", "classes",       "image_channels"};
    for (int i = 0; i < 300; ++i) {
      const std::size_t which = uniform(3);
      SafetensorsParts parts = split(originals[which]);
      nlohmann::json config = nlohmann::json::parse(parts.header["__metadata__"]["config"].get<std::string>());
      std::string field = fields[uniform(fields.size())];
      if (which == 2 && field == "classifier_depth") field = "classifier_width";
      const int before = config["network"][field].get<int>();
      const int after = i % 3 == 0 ? 512 : std::max(1, before + 1 + static_cast<int>(uniform(8)));
      config["network"][field] = after;
      parts.header["__metadata__"]["config"] = config.dump(2);
      EXPECT_FALSE(feed(join(parts), tallies["configs"])) << field << " " << before << " -> " << after;
    }
  }
};

TEST_F(CheckpointFuzz, EveryInputIsRefusedInOneLineOrLoads) {
  Fuzzer fuzz;
  fuzz.originals = {checkpoint_of(agent::ClassifierKind::Paper, "paper"),
                    checkpoint_of(agent::ClassifierKind::Strided, "strided"),
                    checkpoint_of(agent::ClassifierKind::ResNet18, "resnet"),
                    read_bytes(fs::path(SCOUT_SOURCE_DIR) / "tests/data/mnist-8k-v1.safetensors")};
  // Scout's own files load, and so do they split and joined again by the fuzzer's writer.
  for (const std::string& original : fuzz.originals) {
    EXPECT_TRUE(feed(original, fuzz.tallies["original"]));
    EXPECT_TRUE(feed(join(split(original)), fuzz.tallies["original"]));
  }
  ASSERT_EQ(fuzz.tallies["original"].accepted, 8);
  fuzz.random_bytes();
  fuzz.raw_flips();
  fuzz.header_text();
  fuzz.header_fields();
  fuzz.tensor_bytes();
  fuzz.configs();

  int cases = 0;
  for (const auto& [kind, tally] : fuzz.tallies) {
    std::printf("%-16s %5d refused  %5d accepted  peak %6ld KiB\n", kind.c_str(), tally.refused, tally.accepted,
                tally.peak_kib);
    cases += tally.refused + tally.accepted;
    // No input made the process allocate much beyond what Scout's own files take to load (their
    // tensors and the agent built from them): a width-512 config alone would take gigabytes.
    EXPECT_LE(tally.peak_kib, fuzz.tallies["original"].peak_kib + kInputSlackKiB) << kind;
  }
  EXPECT_GE(cases, 5000);
  EXPECT_GT(fuzz.tallies["header text"].refused, 1000);
  EXPECT_GT(fuzz.tallies["header fields"].refused, 500);
}

// Each layer of the check names what it found, in one line.
TEST_F(CheckpointFuzz, RefusalsNameWhatIsWrong) {
  const std::string original = checkpoint_of(agent::ClassifierKind::Paper, "paper");
  const auto refusal = [](const std::string& bytes) -> std::string {
    try {
      open_checkpoint_bytes(bytes, "f.safetensors");
    } catch (const InputError& e) {
      return e.what();
    }
    return "accepted";
  };
  SafetensorsParts parts = split(original);
  const std::string first = parts.header.begin().key();

  SafetensorsParts dtype = parts;
  dtype.header[first]["dtype"] = "F16";
  EXPECT_NE(refusal(join(dtype)).find("tensor '" + first + "': dtype \"F16\""), std::string::npos)
      << refusal(join(dtype));

  SafetensorsParts shorter = parts;
  shorter.data.resize(shorter.data.size() - 4);
  EXPECT_NE(refusal(join(shorter)).find("the data after the header is"), std::string::npos) << refusal(join(shorter));

  SafetensorsParts renamed = parts;
  renamed.header["agent.renamed"] = renamed.header[first];
  renamed.header.erase(first);
  EXPECT_NE(refusal(join(renamed)).find(first + " is missing"), std::string::npos) << refusal(join(renamed));

  SafetensorsParts code = parts;
  code.header["__metadata__"]["format"] = "pickle";
  EXPECT_NE(refusal(join(code)).find("not a Scout checkpoint"), std::string::npos) << refusal(join(code));

  EXPECT_EQ(refusal(join(parts)), "accepted");
}

}  // namespace
}  // namespace scout::learn
