// Hostile checkpoints (issues 24 and 42), each kind built from a real file: a checkpoint Scout's
// own writer makes in the test (weights, Adam's state, the schedule), with its safetensors layout
// edited (lengths, offsets, dtypes, shapes, a deep or huge header, a name twice) or what it says
// edited (a missing or misshapen tensor, NaN, a cursor at INT_MAX, Adam's step at INT64_MAX, a
// padded config), with models/mnist.safetensors loaded beside them as valid. Each is refused with
// one line naming the file; each case runs in a forked child whose peak resident
// size above its start is measured (VmHWM, reset through /proc/self/clear_refs; the input,
// already in memory, is not counted) and printed, and held to kRefusalSlackKiB. A few kinds also go through the real
// `scout eval`, `export`, `run --checkpoint` and `train --resume`: exit status 1, one line.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <torch/torch.h>
#include <torch/version.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "learn/internal/checkpoint.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/safetensors_edit.hpp"
#include "tests/support/training_fixture.hpp"

namespace scout::learn {
namespace {

using namespace scout::learn::test_support;

// AddressSanitizer's redzones, its shadow memory and its quarantine of freed blocks keep several
// times the memory resident that a Release build does (the CI's ASan pass runs this test too).
#if defined(__SANITIZE_ADDRESS__)
constexpr long kSanitizerFactor = 4;
#else
constexpr long kSanitizerFactor = 1;
#endif

// What refusing an input may allocate beyond the input itself; a valid tiny checkpoint resumed
// takes about 13 MiB. For a command, beyond the peak of exporting a valid checkpoint.
constexpr long kRefusalSlackKiB = 16 * 1024 * kSanitizerFactor;

// --- One case in a child process ------------------------------------------------------------------

struct Outcome {
  int status = -1;      ///< the child's: 0 accepted, 1 refused with an InputError, 2 another exception
  int signal = 0;       ///< the signal that ended it, if one did
  std::string message;  ///< the refusal (or the exception)
  long peak_kib = 0;    ///< peak resident size above the child's own at the start
  double seconds = 0;
};

long status_kib(const char* field) {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind(field, 0) == 0) return std::stol(line.substr(std::string(field).size()));
  return 0;
}

// Runs `body` in a forked child (a crash or a hang ends only the child: 60 s alarm) and measures
// its peak resident size from a reset high-water mark.
Outcome run_isolated(const std::function<void()>& body) {
  int fds[2];
  EXPECT_EQ(pipe(fds), 0);
  const auto start = std::chrono::steady_clock::now();
  const pid_t child = fork();
  if (child == 0) {
    close(fds[0]);
    alarm(60);
    std::ofstream("/proc/self/clear_refs") << "5";  // VmHWM := VmRSS
    const long base = status_kib("VmRSS:");
    int status = 0;
    std::string message = "accepted";
    try {
      body();
    } catch (const InputError& e) {
      status = 1;
      message = e.what();
    } catch (const std::exception& e) {
      status = 2;
      message = e.what();
    }
    message = std::to_string(status_kib("VmHWM:") - base) + " " + message;
    if (write(fds[1], message.data(), message.size()) < 0) status = 3;
    _exit(status);
  }
  close(fds[1]);
  std::string text;
  char buffer[4096];
  for (ssize_t n; (n = read(fds[0], buffer, sizeof buffer)) > 0;) text.append(buffer, static_cast<std::size_t>(n));
  close(fds[0]);
  int raw = 0;
  waitpid(child, &raw, 0);
  Outcome o;
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  o.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  o.signal = WIFSIGNALED(raw) ? WTERMSIG(raw) : 0;
  const std::size_t space = text.find(' ');
  if (space != std::string::npos) {
    o.peak_kib = std::stol(text.substr(0, space));
    o.message = text.substr(space + 1);
  }
  return o;
}

// What a resumed run does with a file: open it, then load its weights and Adam's state. The bytes
// are moved in, as open_checkpoint moves the file it read.
void open_and_resume(std::string bytes, const std::string& origin) {
  const Checkpoint checkpoint = open_checkpoint_bytes(std::move(bytes), origin);
  const TrainConfig& config = checkpoint.info().config;
  agent::Agent agent(config.network);
  torch::optim::Adam adam(agent->parameters(), torch::optim::AdamOptions(config.learning_rate));
  checkpoint.contents().load_into(*agent, &adam);
}

// The case's refusal: one line, naming the file, containing `expected`; within its memory bound.
void expect_refused(const std::string& kind, const Outcome& o, const std::string& origin, const std::string& expected) {
  std::printf("%-52s %7ld KiB peak %6.0f ms  %s\n", kind.c_str(), o.peak_kib, o.seconds * 1000,
              o.message.substr(0, 150).c_str());
  EXPECT_EQ(o.signal, 0) << kind;
  EXPECT_EQ(o.status, 1) << kind << ": " << o.message;
  EXPECT_EQ(o.message.rfind(origin + ": ", 0), 0u) << kind << ": " << o.message;
  EXPECT_EQ(o.message.find('\n'), std::string::npos) << kind << ": " << o.message;
  EXPECT_NE(o.message.find(expected), std::string::npos) << kind << ": expected '" << expected << "' in " << o.message;
  EXPECT_LT(o.peak_kib, kRefusalSlackKiB) << kind;
}

// --- Edits of a real file -----------------------------------------------------------------------

using scout::testing::assemble;
using scout::testing::join;
using scout::testing::join_text;
using scout::testing::SafetensorsParts;
using scout::testing::split;
using scout::testing::TensorEntry;
using scout::testing::tensors_of;

// The file with its header edited.
std::string with_header(const std::string& real, const std::function<void(nlohmann::ordered_json&)>& edit) {
  SafetensorsParts parts = split(real);
  edit(parts.header);
  return join(parts);
}

// The file with one metadata entry (JSON text) edited.
std::string with_metadata(const std::string& real, const std::string& key,
                          const std::function<void(nlohmann::ordered_json&)>& edit) {
  return with_header(real, [&](nlohmann::ordered_json& header) {
    nlohmann::ordered_json value = nlohmann::ordered_json::parse(header["__metadata__"][key].get<std::string>());
    edit(value);
    header["__metadata__"][key] = value.dump();
  });
}

// The file with its tensors (in data order) edited and laid out again back to back.
std::string with_tensors(const std::string& real, const std::function<void(std::vector<TensorEntry>&)>& edit) {
  const SafetensorsParts parts = split(real);
  std::vector<TensorEntry> tensors = tensors_of(parts);
  edit(tensors);
  return join(assemble(tensors, parts.header["__metadata__"]));
}

TensorEntry& named(std::vector<TensorEntry>& tensors, const std::string& prefix, const std::string& suffix = "") {
  for (TensorEntry& t : tensors)
    if (t.name.rfind(prefix, 0) == 0 && t.name.size() >= suffix.size() &&
        t.name.compare(t.name.size() - suffix.size(), suffix.size(), suffix) == 0)
      return t;
  throw std::runtime_error("no tensor " + prefix + "..." + suffix);
}

std::string resnet_512(nlohmann::ordered_json& config) {
  config["network"]["classifier"] = "resnet18";
  config["network"]["classifier_width"] = 512;
  return config.dump();
}

std::string deep_json(int depth) { return std::string(static_cast<std::size_t>(depth), '[') + std::string(depth, ']'); }

// --- The cases --------------------------------------------------------------------------------

struct HostileCase {
  std::string kind;
  std::function<std::string(const std::string& real)> make;  // from the real checkpoint's bytes
  std::string expected;                                      // in the refusal
};

// The header: its length, size and JSON against the file and the parser's bounds.
std::vector<HostileCase> layout_cases() {
  return {
      {"a header length larger than the file",
       [](const std::string& real) { return scout::testing::length_prefix(real.size()) + real.substr(8); },
       "the header length says"},
      {"a header length of 2^63",
       [](const std::string& real) { return scout::testing::length_prefix(std::uint64_t{1} << 63) + real.substr(8); },
       "the header length says"},
      {"a 5 MiB header (spaces)",
       [](const std::string& real) {
         const SafetensorsParts parts = split(real);
         return join_text(parts.header.dump() + std::string(std::size_t{5} << 20, ' '), parts.data);
       },
       "more than the 4194304 Scout reads"},
      {"a header of 300,000 values",
       [](const std::string& real) {
         const SafetensorsParts parts = split(real);
         std::string list = "[0";
         for (int i = 1; i < 300000; ++i) list += ",0";
         std::string text = parts.header.dump();
         text.insert(1, "\"x\":{\"dtype\":\"F32\",\"shape\":" + list + "],\"data_offsets\":[0,0]},");
         return join_text(text, parts.data);
       },
       "the header holds more than"},
      {"a 400,000-deep JSON header",
       [](const std::string& real) {
         const SafetensorsParts parts = split(real);
         std::string text = parts.header.dump();
         text.insert(1, "\"x\":" + deep_json(400000) + ",");
         return join_text(text, parts.data);
       },
       "the header nests deeper than 3 levels"},
      {"a tensor named twice",
       [](const std::string& real) {
         const SafetensorsParts parts = split(real);
         const auto first = parts.header.items().begin();
         std::string text = parts.header.dump();
         text.insert(1, nlohmann::ordered_json(first.key()).dump() + ":" + first.value().dump() + ",");
         return join_text(text, parts.data);
       },
       "twice"},
  };
}

// The tensors' byte ranges and dtypes against the file's length and each other.
std::vector<HostileCase> range_cases() {
  return {
      {"offsets past the end",
       [](const std::string& real) {
         return with_header(real, [](nlohmann::ordered_json& h) {
           auto& offsets = h.begin().value()["data_offsets"];
           offsets[1] = offsets[1].get<std::uint64_t>() + (std::uint64_t{1} << 40);
         });
       },
       "the data after the header is"},
      {"offsets that run backwards",
       [](const std::string& real) {
         return with_header(real, [](nlohmann::ordered_json& h) {
           auto& offsets = h.begin().value()["data_offsets"];
           offsets = {offsets[1], offsets[0]};
         });
       },
       "run backwards"},
      {"overlapping tensors",
       [](const std::string& real) {
         return with_header(real, [](nlohmann::ordered_json& h) {
           auto second = std::next(h.begin());
           auto& offsets = second.value()["data_offsets"];
           offsets = {offsets[0].get<std::uint64_t>() - 4, offsets[1].get<std::uint64_t>() - 4};
         });
       },
       "without gap or overlap"},
      {"a gap of 64 bytes between two tensors",
       [](const std::string& real) {
         SafetensorsParts parts = split(real);
         const std::uint64_t cut = std::next(parts.header.begin()).value()["data_offsets"][0].get<std::uint64_t>();
         parts.data.insert(cut, 64, '\0');
         for (auto& [name, entry] : parts.header.items()) {
           if (name == "__metadata__") continue;
           auto& offsets = entry["data_offsets"];
           for (auto& o : offsets)
             if (o.get<std::uint64_t>() >= cut && !(&entry == &parts.header.begin().value()))
               o = o.get<std::uint64_t>() + 64;
         }
         return join(parts);
       },
       "without gap or overlap"},
      {"64 MiB after the last tensor",
       [](const std::string& real) { return real + std::string(std::size_t{64} << 20, '\0'); },
       "bytes before the file does"},
      {"a dtype Scout does not store (BF16)",
       [](const std::string& real) {
         return with_header(real, [](nlohmann::ordered_json& h) { h.begin().value()["dtype"] = "BF16"; });
       },
       "Scout stores F32 and I64 only"},
      {"a shape that does not match the byte count",
       [](const std::string& real) {
         return with_header(real, [](nlohmann::ordered_json& h) {
           auto& shape = h.begin().value()["shape"];
           shape[0] = shape[0].get<std::int64_t>() + 1;
         });
       },
       "data_offsets give"},
      {"sizes whose product wraps (2^33 + 1, 2^31)",
       [](const std::string& real) {
         return with_header(real, [](nlohmann::ordered_json& h) {
           h.begin().value()["shape"] = {(std::uint64_t{1} << 33) + 1, std::uint64_t{1} << 31};
         });
       },
       "more than 2^60 elements"},
  };
}

// The tensors against the networks the config describes.
std::vector<HostileCase> tensor_cases() {
  return {
      {"a misshapen weight (its dimensions swapped)",
       [](const std::string& real) {
         return with_tensors(real, [](std::vector<TensorEntry>& t) {
           for (TensorEntry& e : t) {
             auto& shape = e.entry["shape"];
             if (e.name.rfind("agent.", 0) == 0 && shape.size() >= 2 && shape[0] != shape[1]) {
               std::swap(shape[0], shape[1]);
               return;
             }
           }
         });
       },
       "the config gives"},
      {"a missing weight",
       [](const std::string& real) {
         return with_tensors(real, [](std::vector<TensorEntry>& t) {
           t.erase(
               std::find_if(t.begin(), t.end(), [](const TensorEntry& e) { return e.name.rfind("agent.", 0) == 0; }));
         });
       },
       "is missing"},
      {"an extra tensor",
       [](const std::string& real) {
         return with_tensors(real, [](std::vector<TensorEntry>& t) {
           t.push_back({"agent.extra", {{"dtype", "F32"}, {"shape", {1}}}, std::string(4, '\0')});
         });
       },
       "agent.extra is not a tensor of its networks"},
      {"NaN in a weight",
       [](const std::string& real) {
         return with_tensors(real, [](std::vector<TensorEntry>& t) {
           const float nan = std::nanf("");
           std::memcpy(named(t, "agent.", ".weight").bytes.data(), &nan, sizeof nan);
         });
       },
       "not finite"},
  };
}

// The progress's numbers and Adam's step against the schedule and their ranges.
std::vector<HostileCase> progress_cases() {
  return {
      {"a progress cursor at INT_MAX",
       [](const std::string& real) {
         return with_metadata(real, "progress", [](nlohmann::ordered_json& p) {
           p["stage"] = 1;
           p["epoch"] = std::numeric_limits<int>::max();
         });
       },
       "progress: epoch: expected 0 to 100000, got 2147483647"},
      {"a progress cursor past the config's schedule (mode i, epoch 50 of 1)",
       [](const std::string& real) {
         return with_metadata(real, "progress", [](nlohmann::ordered_json& p) {
           p["stage"] = 1;
           p["epoch"] = 50;
         });
       },
       "outside the config's schedule (mode i has 1 epochs)"},
      {"a cursor epoch of 2^32 + 1 (what get<int> reads as 1)",
       [](const std::string& real) {
         return with_metadata(real, "progress",
                              [](nlohmann::ordered_json& p) { p["epoch"] = (std::uint64_t{1} << 32) + 1; });
       },
       "progress: epoch: expected 0 to 100000"},
      {"a resume's threads at INT_MAX",
       [](const std::string& real) {
         return with_metadata(real, "progress",
                              [](nlohmann::ordered_json& p) { p["threads"] = std::numeric_limits<int>::max(); });
       },
       "progress: threads: expected 0 to 256"},
      {"a history of 1,000,000 zeros (2 MB of JSON, 16 MB as a tree)",
       [](const std::string& real) {
         return with_metadata(real, "progress", [](nlohmann::ordered_json& p) {
           p["history"] = nlohmann::ordered_json::array();
           for (int i = 0; i < 1000000; ++i) p["history"].push_back(0);
         });
       },
       "progress: more than"},
      {"Adam's step at INT64_MAX",
       [](const std::string& real) {
         return with_tensors(real, [](std::vector<TensorEntry>& t) {
           const std::int64_t step = std::numeric_limits<std::int64_t>::max();
           std::memcpy(named(t, "optimizer.", ".step").bytes.data(), &step, sizeof step);
         });
       },
       "Adam steps, expected 1 to"},
  };
}

// The config, Adam's options and the metadata entries against what the writer stores.
std::vector<HostileCase> metadata_cases() {
  return {
      {"a config padded to 16 MB",
       [](const std::string& real) {
         return with_header(real, [](nlohmann::ordered_json& h) {
           h["__metadata__"]["config"] = h["__metadata__"]["config"].get<std::string>() + std::string(16000000, ' ');
         });
       },
       "more than the 4194304 Scout reads"},
      {"a config padded to 1 MB",
       [](const std::string& real) {
         return with_header(real, [](nlohmann::ordered_json& h) {
           h["__metadata__"]["config"] = h["__metadata__"]["config"].get<std::string>() + std::string(1000000, ' ');
         });
       },
       "config: 10"},
      {"30,000-deep JSON in the config",
       [](const std::string& real) {
         return with_header(real, [](nlohmann::ordered_json& h) {
           std::string config = h["__metadata__"]["config"].get<std::string>();
           config.insert(1, "\"x\": " + deep_json(30000) + ",");
           h["__metadata__"]["config"] = config;
         });
       },
       "config: arrays and objects nested more than 16 deep"},
      {"ResNet-18 width 512 config in a small file",
       [](const std::string& real) {
         return with_metadata(real, "config", [](nlohmann::ordered_json& c) { resnet_512(c); });
       },
       "config: the network has"},
      {"a 0-d Adam moment",
       [](const std::string& real) {
         return with_tensors(real, [](std::vector<TensorEntry>& t) {
           TensorEntry& moment = named(t, "optimizer.", ".exp_avg_sq");
           moment.entry["shape"] = nlohmann::ordered_json::array();
           moment.bytes.resize(4);
         });
       },
       "exp_avg_sq: F32 [], expected F32 ["},
      {"NaN in Adam's betas (JSON null)",
       [](const std::string& real) {
         return with_metadata(real, "optimizer", [](nlohmann::ordered_json& o) { o["betas"][0] = std::nan(""); });
       },
       "betas: expected two numbers in [0, 1)"},
      {"Adam's amsgrad true",
       [](const std::string& real) {
         return with_metadata(real, "optimizer", [](nlohmann::ordered_json& o) { o["amsgrad"] = true; });
       },
       "amsgrad: expected false"},
      {"a negative learning rate",
       [](const std::string& real) {
         return with_metadata(real, "optimizer", [](nlohmann::ordered_json& o) { o["lr"] = -1; });
       },
       "lr: expected a finite number > 0"},
      {"a metadata entry Scout does not write",
       [](const std::string& real) {
         return with_header(real, [](nlohmann::ordered_json& h) { h["__metadata__"]["code"] = "import os"; });
       },
       "code is not an entry Scout's writer stores"},
      {"a future format version",
       [](const std::string& real) {
         return with_header(real, [](nlohmann::ordered_json& h) { h["__metadata__"]["format_version"] = "3"; });
       },
       "format_version: this build reads 2, the file has 3"},
  };
}

// Every kind of the layout (the parser's checks) and of the contents (what Scout's writer makes).
std::vector<HostileCase> joined(std::initializer_list<std::vector<HostileCase>> parts) {
  std::vector<HostileCase> all;
  for (const std::vector<HostileCase>& part : parts) all.insert(all.end(), part.begin(), part.end());
  return all;
}
std::vector<HostileCase> all_layout_cases() { return joined({layout_cases(), range_cases()}); }
std::vector<HostileCase> content_cases() { return joined({tensor_cases(), progress_cases(), metadata_cases()}); }

class HostileCheckpoints : public Resume {
 protected:
  void SetUp() override {
    Resume::SetUp();
    Trainer trainer(config({1, 1, 1}), run_dir("real"), kThreads);
    ASSERT_EQ(trainer.run({}).outcome, TrainOutcome::Finished);
    real_ = read_bytes(temp_.path() / "real" / kCheckpointFile);
  }

  void run_cases(const std::vector<HostileCase>& cases) {
    for (const HostileCase& c : cases) {
      std::string bytes = c.make(real_);
      const Outcome o = run_isolated([&] { open_and_resume(std::move(bytes), "hostile.safetensors"); });
      expect_refused(c.kind, o, "hostile.safetensors", c.expected);
    }
  }
  std::string real_;
};

// Scout's own files load, as written and as re-assembled by the test's editor, in a child whose
// peak memory is printed beside the refusals' for comparison.
TEST_F(HostileCheckpoints, TheWritersOwnFilesLoad) {
  const std::string model = read_bytes(fs::path(SCOUT_SOURCE_DIR) / "models/mnist.safetensors");
  struct Own {
    std::string kind, bytes;
    bool resume;  // a checkpoint (weights and Adam), or a model file (weights only)
  };
  for (const Own& own : std::vector<Own>{{"Scout's checkpoint, resumed", real_, true},
                                         {"the same, split and joined again", join(split(real_)), true},
                                         {"models/mnist.safetensors, its networks built", model, false}}) {
    const auto& [kind, bytes, resume] = own;
    const Outcome o = run_isolated([&] {
      if (resume) return open_and_resume(bytes, "f.safetensors");
      load_agent(open_checkpoint_bytes(bytes, "f.safetensors"));
    });
    std::printf("%-52s %7ld KiB peak %6.0f ms  %s\n", kind.c_str(), o.peak_kib, o.seconds * 1000, o.message.c_str());
    EXPECT_EQ(o.status, 0) << kind << ": " << o.message;
  }
}

TEST_F(HostileCheckpoints, LayoutsThatDisagreeWithTheFileAreRefused) { run_cases(all_layout_cases()); }

TEST_F(HostileCheckpoints, ContentsOtherThanTheWritersAreRefused) { run_cases(content_cases()); }

// A file of the older format (a LibTorch zip) is never parsed: the refusal says how to convert it.
TEST_F(HostileCheckpoints, AnOlderFormatFileIsReferredToScoutConvert) {
  const std::string legacy = read_bytes(fs::path(SCOUT_SOURCE_DIR) / "tests/data/mnist-8k-v1.pt");
  const Outcome o = run_isolated([&] { open_and_resume(legacy, "old.pt"); });
  expect_refused("a format-1 .pt file", o, "old.pt", "scout convert old.pt --trusted");
}

// --- Unbounded inputs ---------------------------------------------------------------------------

// A 3 GiB sparse file and a FIFO as checkpoints: refused from what they are, before a byte is
// read (the FIFO without blocking in open(): the child's 60 s alarm would end a blocked one).
TEST_F(HostileCheckpoints, OversizedAndNonRegularFilesAreRefusedBeforeReading) {
  const fs::path sparse = temp_.path() / "sparse.safetensors", fifo = temp_.path() / "fifo.safetensors";
  std::filesystem::resize_file(fs::path(temp_.write("sparse.safetensors", "")), std::uintmax_t{3} << 30);
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  const Outcome big = run_isolated([&] { open_checkpoint(sparse); });
  expect_refused("a 3 GiB sparse file", big, sparse.string(), "more than the 2.0 GiB a Scout checkpoint may have");
  const Outcome pipe = run_isolated([&] { open_checkpoint(fifo); });
  expect_refused("a FIFO", pipe, fifo.string(), "not a regular file (a FIFO, socket or device)");
  EXPECT_LT(pipe.seconds, 10);
}

// --- The real commands ------------------------------------------------------------------------

struct CommandRun {
  int status = -1;
  std::string err;
  long peak_kib = 0;  ///< the process's peak resident size (wait4's ru_maxrss)
  double seconds = 0;
};

CommandRun run_scout(const std::vector<std::string>& args, const fs::path& scratch) {
  std::vector<std::string> argv = {SCOUT_BINARY};
  argv.insert(argv.end(), args.begin(), args.end());
  const auto start = std::chrono::steady_clock::now();
  const pid_t child = scout::testing::spawn(argv, scratch / "out.txt", scratch / "err.txt", [] { alarm(120); });
  int raw = 0;
  rusage usage{};
  wait4(child, &raw, 0, &usage);
  CommandRun r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + WTERMSIG(raw);
  r.err = scout::testing::read_file(scratch / "err.txt");
  r.peak_kib = usage.ru_maxrss;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

class HostileCommands : public HostileCheckpoints {
 protected:
  struct Command {
    std::string name;
    std::vector<std::string> args;
    std::string named;  // the file as the command's error names it
  };
  // `scout eval`, `export`, `run --checkpoint` and `train --resume` of `file` (the last through a
  // run folder whose checkpoint.safetensors links to it).
  std::vector<Command> commands(const fs::path& file) {
    const fs::path out = temp_.path() / "out", run = temp_.path() / "resume";
    fs::create_directories(run);
    fs::remove(run / kCheckpointFile);
    fs::create_symlink(fs::absolute(file), run / kCheckpointFile);
    const std::string images = (data_ / "train-images-idx3-ubyte").string(),
                      labels = (data_ / "train-labels-idx1-ubyte").string();
    return {{"eval",
             {"eval", "--checkpoint", file.string(), "--images", images, "--labels", labels, "--runs", "1"},
             file.string()},
            {"export",
             {"export", file.string(), "--out", (out / "model.safetensors").string(), "--overwrite"},
             file.string()},
            {"run --checkpoint",
             {"run", (temp_.path() / "world.yaml").string(), "--checkpoint", file.string(), "--out",
              (out / "run").string(), "--no-images", "--overwrite"},
             file.string()},
            {"train --resume", {"train", "--resume", run.string()}, (run / kCheckpointFile).string()}};
  }

  // Exit status 1 and one line on stderr that names `named`.
  void expect_one_line(const std::string& kind, const CommandRun& r, const std::string& named, long baseline_kib) {
    std::printf("%-52s %7ld KiB peak %6.0f ms  %s", kind.c_str(), r.peak_kib, r.seconds * 1000,
                r.err.substr(0, 150).c_str());
    if (r.err.size() > 150) std::printf("...\n");
    EXPECT_EQ(r.status, 1) << kind << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << kind << ": " << r.err.substr(0, 2000);
    EXPECT_EQ(r.err.rfind("scout: error: ", 0), 0u) << kind << ": " << r.err.substr(0, 2000);
    EXPECT_NE(r.err.find(named), std::string::npos) << kind << ": " << r.err.substr(0, 2000);
    EXPECT_LT(r.peak_kib, baseline_kib + kRefusalSlackKiB) << kind;
  }
};

// Kinds that crashed (SIGSEGV), ended in exit 3 or ran for 31 s before: each of the four commands
// that read a checkpoint refuses them with exit status 1 and one line, within the peak memory of
// exporting a valid file (plus the slack).
TEST_F(HostileCommands, EveryCommandRefusesHostileCheckpointsInOneLine) {
  const fs::path valid = temp_.path() / "real" / kCheckpointFile;
  fs::create_directories(temp_.path() / "out");
  const CommandRun baseline = run_scout(commands(valid)[1].args, temp_.path());
  ASSERT_EQ(baseline.status, 0) << baseline.err;
  std::printf("%-52s %7ld KiB peak %6.0f ms\n", "export of the valid checkpoint", baseline.peak_kib,
              baseline.seconds * 1000);
  std::vector<HostileCase> all = all_layout_cases(), contents = content_cases();
  all.insert(all.end(), contents.begin(), contents.end());
  const auto case_named = [&](const std::string& name) {
    return *std::find_if(all.begin(), all.end(), [&](const HostileCase& c) { return c.kind.rfind(name, 0) == 0; });
  };
  const std::vector<HostileCase> kinds = {case_named("a 400,000-deep JSON header"),
                                          case_named("Adam's step at INT64_MAX"), case_named("ResNet-18 width 512")};
  std::vector<std::pair<std::string, fs::path>> files;
  for (const HostileCase& c : kinds)
    files.emplace_back(c.kind, temp_.write(c.kind.substr(0, 12) + ".safetensors", c.make(real_)));
  const fs::path sparse = temp_.path() / "sparse.safetensors";
  std::filesystem::resize_file(fs::path(temp_.write("sparse.safetensors", "")), std::uintmax_t{3} << 30);
  files.emplace_back("a 3 GiB sparse file", sparse);
  for (const auto& [kind, file] : files)
    for (const Command& command : commands(file))
      expect_one_line(command.name + ": " + kind, run_scout(command.args, temp_.path()), command.named,
                      baseline.peak_kib);
}

// A FIFO as --images does not block (it did, ignoring SIGTERM); a 1 MB floor.dataset is quoted
// clipped, not repeated whole (it made a 1,000,301-byte line).
TEST_F(HostileCommands, NonRegularAndHugeInputsAreRefusedInOneShortLine) {
  const fs::path fifo = temp_.path() / "images.fifo";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  const fs::path model = fs::path(SCOUT_SOURCE_DIR) / "models/mnist.safetensors";
  const CommandRun piped = run_scout({"eval", "--checkpoint", model.string(), "--images", fifo.string(), "--labels",
                                      (data_ / "train-labels-idx1-ubyte").string()},
                                     temp_.path());
  expect_one_line("eval --images FIFO", piped, fifo.string() + ": not a regular file", 1 << 30);
  EXPECT_LT(piped.seconds, 30);

  const fs::path world = temp_.write("huge.yaml", "floor: {dataset: " + std::string(1000000, 'a') + "}\n");
  const CommandRun huge = run_scout({"run", world.string(), "--out", (temp_.path() / "o").string()}, temp_.path());
  expect_one_line("run with a 1 MB floor.dataset", huge, "floor.dataset: expected", 1 << 30);
  EXPECT_LT(huge.err.size(), 300u) << huge.err.substr(0, 400);
}

}  // namespace
}  // namespace scout::learn
