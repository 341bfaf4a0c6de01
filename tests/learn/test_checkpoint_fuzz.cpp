// Hostile checkpoint and model files: a seeded fuzz loop over random bytes and over Scout's own
// files with mutated bytes, zip records, pickles, class stubs, tensor records and configs. Every
// input is refused with one InputError line naming it, or accepted and loaded; none crashes,
// hangs or makes the process allocate far beyond the file (the peak resident size is checked).
// Mutations that would only meet the zip's CRC are re-packed with correct CRCs, so that they reach
// the checks behind it (learn/internal/archive.hpp).
#include <gtest/gtest.h>
#include <torch/torch.h>
#include <zlib.h>

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
#include "learn/internal/archive.hpp"
#include "learn/internal/checkpoint.hpp"
#include "tests/support/checkpoint_zip.hpp"
#include "tests/support/training_fixture.hpp"

namespace scout::learn {
namespace {

using namespace scout::learn::test_support;

using scout::testing::entry;
using scout::testing::le32;
using scout::testing::pack;
using scout::testing::put32;
using scout::testing::unpack;
using scout::testing::ZipFile;

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
  const std::string origin = "fuzz.pt";
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
  std::mt19937_64 rng{20261202};
  std::vector<std::string> originals;  // three checkpoints and a model file
  std::map<std::string, Tally> tallies;

  std::size_t uniform(std::size_t n) { return static_cast<std::size_t>(rng() % n); }
  const std::string& checkpoint() { return originals[uniform(3)]; }

  // Random bytes, some behind a zip end record.
  void random_bytes() {
    for (int i = 0; i < 1000; ++i) {
      std::string bytes(uniform(4096), '\0');
      for (char& c : bytes) c = static_cast<char>(rng());
      if (i % 2) {  // an empty archive's end record: the signature and 18 zero bytes
        bytes.append("PK\x05\x06", 4);
        bytes.append(18, '\0');
      }
      EXPECT_FALSE(feed(bytes, tallies["random bytes"]));
    }
  }
  // Raw byte flips and truncations of the files as written: a flip in a record fails its CRC.
  void raw_flips() {
    for (int i = 0; i < 1200; ++i) {
      std::string bytes = checkpoint();
      if (i % 6 == 0) {
        bytes.resize(uniform(bytes.size()));
        EXPECT_FALSE(feed(bytes, tallies["truncated"]));
        continue;
      }
      for (int k = 1 + uniform(3); k > 0; --k) bytes[uniform(bytes.size())] ^= static_cast<char>(1 + uniform(255));
      feed(bytes, tallies["raw flips"]);
    }
  }
  // data.pkl flipped, a byte inserted or deleted, or a chunk repeated (memo writes, marks and
  // tensors out of place); re-packed so that it passes the CRC and reaches the checks behind it.
  void pickles() {
    for (int i = 0; i < 1800; ++i) {
      ZipFile zip = unpack(checkpoint());
      std::string& pickle = entry(zip, "data.pkl");
      if (i % 3 == 0) {
        for (int k = 1 + uniform(3); k > 0; --k) pickle[uniform(pickle.size())] ^= static_cast<char>(1 + uniform(255));
      } else if (i % 3 == 1) {
        if (rng() % 2)
          pickle.insert(uniform(pickle.size()), 1, static_cast<char>(rng()));
        else
          pickle.erase(uniform(pickle.size()), 1);
      } else {
        const std::size_t from = uniform(pickle.size()), length = 1 + uniform(64);
        pickle.insert(uniform(pickle.size()), pickle.substr(from, length));
      }
      feed(pack(zip), tallies["data.pkl"]);
    }
  }
  // A tensor record shortened, lengthened, emptied, or an entry added.
  void tensor_records() {
    for (int i = 0; i < 600; ++i) {
      ZipFile zip = unpack(checkpoint());
      std::vector<std::string> records;
      for (const auto& [name, bytes] : zip.entries)
        if (name.rfind("data/", 0) == 0) records.push_back(name);
      std::string& record = entry(zip, records[uniform(records.size())]);
      switch (uniform(4)) {
        case 0:
          record.resize(record.size() ? uniform(record.size()) : 1);
          break;
        case 1:
          record += std::string(1 + uniform(64), '\0');
          break;
        case 2:
          record.clear();
          break;
        case 3:
          zip.entries.emplace_back("extra/" + std::to_string(i), "x");
          break;
      }
      EXPECT_FALSE(feed(pack(zip), tallies["tensor records"]));
    }
  }
  // Class stubs that are not what the writer makes: TorchScript code never reaches the compiler.
  void class_stubs() {
    const std::vector<std::string> lines = {"  def forward(self):\n    return 1\n", "  x : List[int]\n", "import os\n",
                                            "  __parameters__ = [\"a\"]\n", "  y : Tensor"};
    for (int i = 0; i < 300; ++i) {
      ZipFile zip = unpack(checkpoint());
      std::vector<std::string*> stubs;
      for (auto& [name, bytes] : zip.entries)
        if (name.size() > 3 && name.substr(name.size() - 3) == ".py") stubs.push_back(&bytes);
      std::string& stub = *stubs[uniform(stubs.size())];
      if (i % 2)
        stub += lines[uniform(lines.size())];
      else
        stub[uniform(stub.size())] ^= static_cast<char>(1 + uniform(255));
      feed(pack(zip), tallies["class stubs"]);
    }
  }
  // Configs that describe other networks than the weights, from one too narrow to one that would
  // take gigabytes: refused before the agent is built.
  void configs() {
    const std::vector<std::string> fields = {"planner_width",    "planner_depth", "classifier_width",
                                             "classifier_depth", "classes",       "image_channels"};
    for (int i = 0; i < 300; ++i) {
      const std::size_t original = uniform(3);
      ZipFile zip = unpack(originals[original]);
      std::string& pickle = entry(zip, "data.pkl");
      // data.pkl: ... BINUNICODE 'config' BINPUT n BINUNICODE <length> <json> ...
      const std::size_t opcode = pickle.find("config") + 6 + 2;
      ASSERT_EQ(pickle[opcode], 'X');
      const std::uint32_t length = le32(pickle, opcode + 1);
      nlohmann::json config = nlohmann::json::parse(pickle.substr(opcode + 5, length));
      // ResNet-18 always has four stages: its classifier_depth changes nothing (and loads).
      std::string field = fields[uniform(fields.size())];
      if (original == 2 && field == "classifier_depth") field = "classifier_width";
      const int before = config["network"][field].get<int>();
      const int after = i % 3 == 0 ? 512 : std::max(1, before + 1 + static_cast<int>(uniform(8)));
      config["network"][field] = after;
      const std::string text = config.dump(2);
      std::string replaced = "X";
      put32(replaced, static_cast<std::uint32_t>(text.size()));
      pickle.replace(opcode, 5 + length, replaced + text);
      EXPECT_FALSE(feed(pack(zip), tallies["configs"])) << field << " " << before << " -> " << after;
    }
  }
};

TEST_F(CheckpointFuzz, EveryInputIsRefusedInOneLineOrLoads) {
  Fuzzer fuzz;
  fuzz.originals = {checkpoint_of(agent::ClassifierKind::Paper, "paper"),
                    checkpoint_of(agent::ClassifierKind::Strided, "strided"),
                    checkpoint_of(agent::ClassifierKind::ResNet18, "resnet"),
                    read_bytes(fs::path(SCOUT_SOURCE_DIR) / "tests/data/mnist-8k-v1.pt")};
  // Scout's own files load, and so do they re-packed by the fuzzer's writer.
  for (const std::string& original : fuzz.originals) {
    EXPECT_TRUE(feed(original, fuzz.tallies["original"]));
    EXPECT_TRUE(feed(pack(unpack(original)), fuzz.tallies["original"]));
  }
  ASSERT_EQ(fuzz.tallies["original"].accepted, 8);
  fuzz.random_bytes();
  fuzz.raw_flips();
  fuzz.pickles();
  fuzz.tensor_records();
  fuzz.class_stubs();
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
  EXPECT_GT(fuzz.tallies["data.pkl"].refused, 1000);
}

// Each layer of the check names what it found, in one line.
TEST_F(CheckpointFuzz, RefusalsNameWhatIsWrong) {
  const std::string original = checkpoint_of(agent::ClassifierKind::Paper, "paper");
  const auto refusal = [](const std::string& bytes) -> std::string {
    try {
      open_checkpoint_bytes(bytes, "f.pt");
    } catch (const InputError& e) {
      return e.what();
    }
    return "accepted";
  };
  std::string flipped = original;
  ZipFile zip = unpack(original);
  // A flipped byte in the first tensor record.
  const std::size_t record = original.find(zip.folder + "/data/0");
  flipped[record + 200] ^= 1;
  EXPECT_NE(refusal(flipped).find("CRC-32"), std::string::npos) << refusal(flipped);

  ZipFile code = zip;
  entry(code, "code/__torch__.py") += "  def forward(self):\n";
  EXPECT_NE(refusal(pack(code)).find("code/__torch__.py:"), std::string::npos) << refusal(pack(code));

  ZipFile shorter = zip;
  entry(shorter, "data/0").resize(4);
  EXPECT_NE(refusal(pack(shorter)).find("storage 0 declares"), std::string::npos) << refusal(pack(shorter));

  ZipFile global = zip;
  std::string& pickle = entry(global, "data.pkl");
  const std::size_t at = pickle.find("collections\nOrderedDict");
  ASSERT_NE(at, std::string::npos);
  pickle.replace(at, 23, "os\nsystem\n\n\n\n\n\n\n\n\n\n\n\n");  // the same length
  EXPECT_NE(refusal(pack(global)).find("global 'os system'"), std::string::npos) << refusal(pack(global));

  EXPECT_EQ(refusal(pack(zip)), "accepted");
}

}  // namespace
}  // namespace scout::learn
