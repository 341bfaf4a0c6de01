// Hostile checkpoint and model files: a seeded fuzz loop over random bytes and over Scout's own
// files with mutated bytes, zip records, pickles, class stubs, tensor records and configs. Every
// input is refused with one InputError line naming it, or accepted and loaded; none crashes,
// hangs or makes the process allocate far beyond the file (the peak resident size is checked).
// Mutations that would only meet the zip's CRC are re-packed with correct CRCs, so that they reach
// the checks behind it (learn/internal/archive.hpp).
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <torch/torch.h>
#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "learn/internal/archive.hpp"
#include "learn/internal/checkpoint.hpp"
#include "tests/support/training_fixture.hpp"

namespace scout::learn {
namespace {

using namespace scout::learn::test_support;

// --- A zip reader and a stored-only writer, for re-packing mutated entries ----------------------

struct ZipFile {
  std::string folder;
  std::vector<std::pair<std::string, std::string>> entries;  // name (inside the folder), bytes
};

std::uint32_t le32(const std::string& b, std::size_t at) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(b.at(at + i));
  return v;
}
std::uint16_t le16(const std::string& b, std::size_t at) {
  return static_cast<std::uint16_t>(static_cast<unsigned char>(b.at(at)) |
                                    (static_cast<unsigned char>(b.at(at + 1)) << 8));
}
void put16(std::string& out, std::uint32_t v) {
  out.push_back(static_cast<char>(v & 0xff));
  out.push_back(static_cast<char>((v >> 8) & 0xff));
}
void put32(std::string& out, std::uint32_t v) {
  put16(out, v & 0xffff);
  put16(out, v >> 16);
}

// Scout's own (valid) archives only: no zip64 sizes, methods 0 and 8.
ZipFile unpack(const std::string& zip) {
  const std::size_t end = zip.size() - 22;
  const std::uint16_t count = le16(zip, end + 10);
  std::size_t at = le32(zip, end + 16);
  ZipFile out;
  for (int i = 0; i < count; ++i) {
    const std::uint16_t method = le16(zip, at + 10);
    const std::uint32_t compressed = le32(zip, at + 20), size = le32(zip, at + 24);
    const std::uint16_t name_length = le16(zip, at + 28);
    const std::string full = zip.substr(at + 46, name_length);
    const std::uint32_t header = le32(zip, at + 42);
    at += 46 + name_length + le16(zip, at + 30) + le16(zip, at + 32);
    const std::size_t data = header + 30 + le16(zip, header + 26) + le16(zip, header + 28);
    std::string bytes = zip.substr(data, compressed);
    if (method == 8) {
      std::string inflated(size, '\0');
      z_stream z{};
      inflateInit2(&z, -MAX_WBITS);
      z.next_in = reinterpret_cast<Bytef*>(bytes.data());
      z.avail_in = static_cast<uInt>(bytes.size());
      z.next_out = reinterpret_cast<Bytef*>(inflated.data());
      z.avail_out = static_cast<uInt>(inflated.size());
      EXPECT_EQ(inflate(&z, Z_FINISH), Z_STREAM_END);
      inflateEnd(&z);
      bytes = std::move(inflated);
    }
    out.folder = full.substr(0, full.find('/'));
    out.entries.emplace_back(full.substr(full.find('/') + 1), std::move(bytes));
  }
  return out;
}

std::string pack(const ZipFile& zip) {
  std::string out, directory;
  for (const auto& [name, bytes] : zip.entries) {
    const std::string full = zip.folder + "/" + name;
    const auto crc = static_cast<std::uint32_t>(crc32_z(0, reinterpret_cast<const Bytef*>(bytes.data()), bytes.size()));
    const auto offset = static_cast<std::uint32_t>(out.size());
    for (std::string* record : {&out, &directory}) {
      const bool central = record == &directory;
      put32(*record, central ? 0x02014b50 : 0x04034b50);
      if (central) put16(*record, 20);  // made by
      put16(*record, 20);               // needed
      put16(*record, 0);                // flags
      put16(*record, 0);                // stored
      put32(*record, 0);                // time, date
      put32(*record, crc);
      put32(*record, static_cast<std::uint32_t>(bytes.size()));
      put32(*record, static_cast<std::uint32_t>(bytes.size()));
      put16(*record, static_cast<std::uint32_t>(full.size()));
      put16(*record, 0);  // extra
      if (central) {
        put16(*record, 0);  // comment
        put16(*record, 0);  // disk
        put16(*record, 0);  // internal attributes
        put32(*record, 0);  // external attributes
        put32(*record, offset);
      }
      *record += full;
      if (!central) *record += bytes;
    }
  }
  const auto directory_offset = static_cast<std::uint32_t>(out.size());
  out += directory;
  put32(out, 0x06054b50);
  put32(out, 0);
  put16(out, static_cast<std::uint32_t>(zip.entries.size()));
  put16(out, static_cast<std::uint32_t>(zip.entries.size()));
  put32(out, static_cast<std::uint32_t>(directory.size()));
  put32(out, directory_offset);
  put16(out, 0);
  return out;
}

std::string& entry(ZipFile& zip, const std::string& name) {
  for (auto& [n, bytes] : zip.entries)
    if (n == name) return bytes;
  throw std::runtime_error("no entry " + name);
}

// --- The loop ------------------------------------------------------------------------------------

long peak_rss_kib() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss;
}

struct Tally {
  int accepted = 0, refused = 0;
};

// Feeds one input to open_checkpoint_bytes and loads its weights, as a resumed run does. Returns whether it was
// accepted; anything but a one-line InputError naming the input fails the test.
bool feed(const std::string& bytes, Tally& tally) {
  const std::string origin = "fuzz.pt";
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

TEST_F(CheckpointFuzz, EveryInputIsRefusedInOneLineOrLoads) {
  constexpr std::uint64_t kSeed = 20261202;
  std::mt19937_64 rng(kSeed);
  const auto uniform = [&](std::size_t n) { return static_cast<std::size_t>(rng() % n); };
  const std::vector<std::string> originals = {checkpoint_of(agent::ClassifierKind::Paper, "paper"),
                                              checkpoint_of(agent::ClassifierKind::Strided, "strided"),
                                              checkpoint_of(agent::ClassifierKind::ResNet18, "resnet"),
                                              read_bytes(fs::path(SCOUT_SOURCE_DIR) / "tests/data/mnist-8k-v1.pt")};
  const long rss_before = peak_rss_kib();
  std::map<std::string, Tally> tallies;

  // Scout's own files load, and so do they re-packed by the fuzzer's writer.
  for (const std::string& original : originals) {
    EXPECT_TRUE(feed(original, tallies["original"]));
    EXPECT_TRUE(feed(pack(unpack(original)), tallies["original"]));
  }
  ASSERT_EQ(tallies["original"].accepted, 8);

  // Random bytes, some behind a zip end record.
  for (int i = 0; i < 1000; ++i) {
    std::string bytes(uniform(4096), '\0');
    for (char& c : bytes) c = static_cast<char>(rng());
    if (i % 2) {  // an empty archive's end record: the signature and 18 zero bytes
      bytes.append("PK\x05\x06", 4);
      bytes.append(18, '\0');
    }
    EXPECT_FALSE(feed(bytes, tallies["random bytes"]));
  }
  // Raw byte flips and truncations of the files as written: a flip in a record fails its CRC.
  for (int i = 0; i < 1200; ++i) {
    std::string bytes = originals[uniform(3)];
    if (i % 6 == 0) {
      bytes.resize(uniform(bytes.size()));
      EXPECT_FALSE(feed(bytes, tallies["truncated"]));
      continue;
    }
    for (int k = 1 + uniform(3); k > 0; --k) bytes[uniform(bytes.size())] ^= static_cast<char>(1 + uniform(255));
    feed(bytes, tallies["raw flips"]);
  }
  // Re-packed mutations, so that they pass the CRC and reach the checks behind it.
  for (int i = 0; i < 2400; ++i) {
    const std::string& original = originals[uniform(3)];
    ZipFile zip = unpack(original);
    std::string& pickle = entry(zip, "data.pkl");
    switch (i % 4) {
      case 0:  // flipped bytes of data.pkl: opcodes, lengths, memo indices, sizes and strides
        for (int k = 1 + uniform(3); k > 0; --k) pickle[uniform(pickle.size())] ^= static_cast<char>(1 + uniform(255));
        break;
      case 1:  // a byte of data.pkl inserted or deleted
        if (rng() % 2)
          pickle.insert(uniform(pickle.size()), 1, static_cast<char>(rng()));
        else
          pickle.erase(uniform(pickle.size()), 1);
        break;
      case 2: {  // a chunk of data.pkl repeated (memo writes, marks and tensors out of place)
        const std::size_t from = uniform(pickle.size()), length = 1 + uniform(64);
        pickle.insert(uniform(pickle.size()), pickle.substr(from, length));
        break;
      }
      case 3: {  // a tensor record shortened, lengthened, removed, or an entry added
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
        continue;
      }
    }
    feed(pack(zip), tallies["data.pkl"]);
  }
  // Class stubs that are not what the writer makes: TorchScript code never reaches the compiler.
  const std::vector<std::string> lines = {"  def forward(self):\n    return 1\n", "  x : List[int]\n", "import os\n",
                                          "  __parameters__ = [\"a\"]\n", "  y : Tensor"};
  for (int i = 0; i < 300; ++i) {
    ZipFile zip = unpack(originals[uniform(3)]);
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
  // Configs that describe other networks than the weights, from one too narrow to one that would
  // take gigabytes: refused before the agent is built.
  const std::vector<std::string> fields = {"planner_width",    "planner_depth", "classifier_width",
                                           "classifier_depth", "classes",       "image_channels"};
  for (int i = 0; i < 300; ++i) {
    const std::size_t original = uniform(3);
    ZipFile zip = unpack(originals[original]);
    std::string& pickle = entry(zip, "data.pkl");
    // data.pkl: ... BINUNICODE 'config' BINPUT n BINUNICODE <length> <json> ...
    const std::size_t key = pickle.find("config");
    ASSERT_NE(key, std::string::npos);
    const std::size_t opcode = key + 6 + 2;
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

  int cases = 0;
  for (const auto& [kind, tally] : tallies) {
    std::printf("%-16s %5d refused  %5d accepted\n", kind.c_str(), tally.refused, tally.accepted);
    cases += tally.refused + tally.accepted;
  }
  EXPECT_GE(cases, 5000);
  EXPECT_GT(tallies["data.pkl"].refused, 1000);
  // No input made the process allocate much: a width-512 config alone would take gigabytes.
  EXPECT_LT(peak_rss_kib() - rss_before, 512 * 1024) << "KiB";
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
