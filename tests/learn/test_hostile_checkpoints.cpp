// Hostile checkpoints (issue 24), each kind built from real files: a checkpoint Scout's own
// writer makes in the test (weights, Adam's state, the schedule), variants written by LibTorch's
// own writer with one part changed (a stride-0 weight, NaN betas), byte-level edits of its pickle
// and zip (a 150,000-deep tuple, a lying local header), and the shipped models/mnist.pt. Each is
// refused with one line naming the file; each case runs in a forked child whose peak resident
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
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "learn/internal/archive.hpp"
#include "learn/internal/checkpoint.hpp"
#include "tests/support/checkpoint_zip.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/training_fixture.hpp"

namespace scout::learn {
namespace {

using namespace scout::learn::test_support;
using scout::testing::list_zip;
using scout::testing::ZipFile;

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

// What a resumed run does with a file: open it, then load its weights and Adam's state.
void open_and_resume(const std::string& bytes, const std::string& origin) {
  const Checkpoint checkpoint = open_checkpoint_bytes(bytes, origin);
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

// --- Variants written by LibTorch's own writer --------------------------------------------------

// What Scout's writer stores, part by part (learn/checkpoint.cpp's checkpoint_archive, repeated
// so that a case can change one part and have LibTorch's writer write it).
struct Parts {
  std::string config, progress;
  agent::Agent agent{nullptr};
  std::unique_ptr<torch::optim::Adam> adam;
  torch::Tensor rng_state = at::detail::getDefaultCPUGenerator().get_state();

  std::string write() const {
    torch::serialize::OutputArchive archive;
    archive.write("scout_checkpoint_format", c10::IValue(static_cast<int64_t>(kCheckpointFormat)));
    archive.write("config", c10::IValue(config));
    archive.write("progress", c10::IValue(progress));
    torch::serialize::OutputArchive weights;
    agent->save(weights);
    archive.write("agent", weights);
    torch::serialize::OutputArchive optimizer;
    adam->save(optimizer);
    archive.write("optimizer", optimizer);
    archive.write("torch_rng_state", rng_state);
    std::ostringstream out;
    archive.save_to(out);
    return std::move(out).str();
  }
  // The first parameter and its Adam state.
  torch::Tensor first_parameter() const { return agent->parameters().front(); }
  torch::optim::AdamParamState& first_state() const {
    // The optimizer's state is keyed by the parameter's TensorImpl: its address as text in 1.13,
    // the pointer itself in 2.x.
#if TORCH_VERSION_MAJOR >= 2
    const auto key = static_cast<void*>(first_parameter().unsafeGetTensorImpl());
#else
    const std::string key = c10::guts::to_string(first_parameter().unsafeGetTensorImpl());
#endif
    return static_cast<torch::optim::AdamParamState&>(*adam->state().at(key));
  }
  torch::optim::AdamOptions& options() const {
    return static_cast<torch::optim::AdamOptions&>(adam->param_groups().front().options());
  }
};

Parts parts_of(const std::string& bytes) {
  const ArchiveContents contents = inspect_archive(bytes);
  Parts p;
  p.config = contents.strings.at("config");
  p.progress = contents.strings.at("progress");
  const Checkpoint checkpoint = open_checkpoint_bytes(bytes, "real.pt");
  const TrainConfig& config = checkpoint.info().config;
  p.agent = agent::Agent(config.network);
  p.adam = std::make_unique<torch::optim::Adam>(p.agent->parameters(), torch::optim::AdamOptions(config.learning_rate));
  checkpoint.contents().load_into(*p.agent, p.adam.get());
  return p;
}

// --- Byte-level edits of data.pkl -------------------------------------------------------------

std::string binunicode(const std::string& text) {
  std::string out = "X";
  scout::testing::put32(out, static_cast<std::uint32_t>(text.size()));
  return out + text;
}

// `depth` one-element tuples around None: ((((None,),),),)
std::string deep_tuple(int depth) { return "N" + std::string(static_cast<std::size_t>(depth), '\x85'); }

// The pickled value after the string `key` (BINUNICODE key, BINPUT n): [begin, end) of it, for
// a value that is one BINUNICODE string or two BINFLOATs and TUPLE2 (Adam's betas).
std::pair<std::size_t, std::size_t> value_after(const std::string& pickle, const std::string& key) {
  const std::size_t at = pickle.find(binunicode(key));
  if (at == std::string::npos) throw std::runtime_error("no key " + key);
  std::size_t v = at + 5 + key.size();
  v += pickle[v] == 'q' ? 2 : pickle[v] == 'r' ? 5 : 0;  // BINPUT, LONG_BINPUT
  if (pickle[v] == 'X') return {v, v + 5 + scout::testing::le32(pickle, v + 1)};
  if (pickle[v] == 'G' && pickle[v + 18] == '\x86') return {v, v + 19};
  throw std::runtime_error("unexpected value after " + key);
}

// The pickle with the value of `key` replaced by `value` (a pickled value).
std::string with_value(const std::string& bytes, const std::string& key, const std::string& value) {
  ZipFile zip = scout::testing::unpack(bytes);
  std::string& pickle = scout::testing::entry(zip, "data.pkl");
  const auto [begin, end] = value_after(pickle, key);
  pickle.replace(begin, end - begin, value);
  return scout::testing::pack(zip);
}

// The pickle with one more attribute of the root, `name` = `value`; the stub unchanged.
std::string with_root_attribute(const std::string& bytes, const std::string& name, const std::string& value) {
  ZipFile zip = scout::testing::unpack(bytes);
  std::string& pickle = scout::testing::entry(zip, "data.pkl");
  // data.pkl ends with the root's SETITEMS, BUILD, BINPUT n, STOP.
  const std::size_t setitems = pickle.rfind("ub");
  pickle.insert(setitems, binunicode(name) + value);
  return scout::testing::pack(zip);
}

std::string with_stub(const std::string& bytes, const std::string& from, const std::string& to) {
  ZipFile zip = scout::testing::unpack(bytes);
  std::string& stub = scout::testing::entry(zip, "code/__torch__.py");
  const std::size_t at = stub.find(from);
  if (at == std::string::npos) throw std::runtime_error("no '" + from + "' in the stub");
  stub.replace(at, from.size(), to);
  return scout::testing::pack(zip);
}

std::string resnet_512(const std::string& config_json) {
  nlohmann::json config = nlohmann::json::parse(config_json);
  config["network"]["classifier"] = "resnet18";
  config["network"]["classifier_width"] = 512;
  return config.dump(2);
}

std::string deep_json(int depth) { return std::string(static_cast<std::size_t>(depth), '[') + std::string(depth, ']'); }

// --- Byte-level edits of the zip --------------------------------------------------------------

// The file with a field of the local header (`field`: its offset there) or of the data
// descriptor (`in_descriptor`) of its first entry compressed with `method` changed.
std::string with_local_field(std::string bytes, std::uint16_t method, std::size_t field, bool in_descriptor,
                             std::uint32_t value) {
  for (const scout::testing::ZipListing& e : list_zip(bytes)) {
    if (e.method != method) continue;
    const std::size_t at = in_descriptor ? e.data + e.compressed + field : e.header + field;
    if (field == 8 && !in_descriptor) {  // the method: 16 bits
      bytes[at] = static_cast<char>(value);
      bytes[at + 1] = 0;
    } else {
      scout::testing::set32(bytes, at, value);
    }
    return bytes;
  }
  throw std::runtime_error("no entry of that method");
}

std::string with_record(const std::string& bytes, std::size_t size) {
  ZipFile zip = scout::testing::unpack(bytes);
  zip.entries.emplace_back("data/9999", std::string(size, '\0'));
  return scout::testing::pack(zip);
}

// --- The cases --------------------------------------------------------------------------------

struct HostileCase {
  std::string kind;
  std::function<std::string(const std::string& real)> make;  // from the real checkpoint's bytes
  std::string expected;                                      // in the refusal
};

std::vector<HostileCase> pickle_cases() {
  return {
      {"150,000-deep tuple in an undeclared attribute",
       [](const std::string& real) { return with_root_attribute(real, "extra", deep_tuple(150000)); },
       "values nested more than 150 deep"},
      {"900,000-deep tuple in progress",
       [](const std::string& real) { return with_value(real, "progress", deep_tuple(900000)); },
       "values nested more than 150 deep"},
      {"150,000-deep tuple in Adam's betas",
       [](const std::string& real) { return with_value(real, "betas", deep_tuple(150000)); },
       "values nested more than 150 deep"},
      {"an attribute the class stub does not declare",
       [](const std::string& real) { return with_root_attribute(real, "extra", binunicode("x")); },
       "extra is not an attribute its class stub (code/__torch__.py) declares"},
      {"a class stub that changes a type (config : int)",
       [](const std::string& real) { return with_stub(real, "config : str", "config : int"); },
       "config is not the int its class stub"},
      {"an attribute missing from the class stub",
       [](const std::string& real) { return with_stub(real, "  progress : str\n", ""); },
       "progress is not an attribute its class stub"},
      {"400,000-deep JSON in the config",
       [](const std::string& real) {
         std::string config = inspect_archive(real).strings.at("config");
         config.insert(1, "\"x\": " + deep_json(400000) + ",");
         return with_value(real, "config", binunicode(config));
       },
       "config: arrays and objects nested more than 16 deep"},
      {"400,000-deep JSON in the progress",
       [](const std::string& real) {
         std::string progress = inspect_archive(real).strings.at("progress");
         progress.insert(1, "\"x\": " + deep_json(400000) + ",");
         return with_value(real, "progress", binunicode(progress));
       },
       "progress: arrays and objects nested more than 16 deep"},
  };
}

std::vector<HostileCase> tensor_cases() {
  return {
      {"a stride-0 weight over one element",
       [](const std::string& real) {
         Parts p = parts_of(real);
         torch::NoGradGuard no_grad;
         p.first_parameter().set_(torch::zeros({1}).expand(p.first_parameter().sizes()));
         return p.write();
       },
       "stride 0 in dimension"},
      {"a stride-0 torch_rng_state of 2^20 elements",
       [](const std::string& real) {
         Parts p = parts_of(real);
         p.rng_state = torch::zeros({1}, torch::kByte).expand({1 << 20});
         return p.write();
       },
       "stride 0 in dimension 0"},
      {"a stride-0 Adam moment",
       [](const std::string& real) {
         Parts p = parts_of(real);
         p.first_state().exp_avg(torch::zeros({1}).expand(p.first_parameter().sizes()));
         return p.write();
       },
       "stride 0 in dimension"},
      {"a 0-d Adam moment",
       [](const std::string& real) {
         Parts p = parts_of(real);
         p.first_state().exp_avg_sq(torch::zeros({}));
         return p.write();
       },
       "exp_avg_sq: Float [], expected Float ["},
      {"sizes [2^33 + 1, 2^31] whose product wraps",
       [](const std::string& real) {
         Parts p = parts_of(real);
         p.rng_state = torch::zeros({1}, torch::kByte).expand({3, 5});  // sizes (3, 5), strides (0, 0)
         ZipFile zip = scout::testing::unpack(p.write());
         std::string& pickle = scout::testing::entry(zip, "data.pkl");
         const std::size_t at = pickle.find(std::string("(K\x03K\x05t(K\x00K\x00t", 12));
         if (at == std::string::npos) throw std::runtime_error("no sizes (3, 5)");
         // LONG1 2^33 + 1 (5 bytes), LONG1 2^31 (5 bytes, the top one 0: positive); strides (2^31, 1).
         const std::string big = std::string("\x8a\x05\x01\x00\x00\x00\x02", 7),
                           half = std::string("\x8a\x05\x00\x00\x00\x80\x00", 7);
         pickle.replace(at, 12, "(" + big + half + "t(" + half + std::string("K\x01t", 3));
         return scout::testing::pack(zip);
       },
       "whose sizes multiply beyond 64 bits"},
      {"ResNet-18 width 512 config + a stride-0 tensor of 2^40",
       [](const std::string& real) {
         Parts p = parts_of(real);
         p.rng_state = torch::zeros({1}, torch::kByte).expand({int64_t{1} << 20, int64_t{1} << 20});
         p.config = resnet_512(p.config);
         return p.write();
       },
       "stride 0 in dimension"},
      {"ResNet-18 width 512 config in a 0.1 MB file",
       [](const std::string& real) {
         return with_value(real, "config", binunicode(resnet_512(inspect_archive(real).strings.at("config"))));
       },
       "config: the network has"},
  };
}

std::vector<HostileCase> zip_and_adam_cases() {
  constexpr std::uint32_t kWrong = 0x12345678;
  return {
      {"a local header that lies about the method",
       [](const std::string& real) { return with_local_field(real, 8, 8, false, 0); },
       "its local header gives another compression method"},
      {"a data descriptor that lies about the CRC",
       [=](const std::string& real) { return with_local_field(real, 8, 4, true, kWrong); },
       "its data descriptor gives another CRC-32 or other sizes"},
      {"a data descriptor that lies about the size",
       [=](const std::string& real) { return with_local_field(real, 0, 12, true, kWrong); },
       "its data descriptor gives another CRC-32 or other sizes"},
      {"a local header that lies about the CRC (no descriptor)",
       [=](const std::string& real) {
         return with_local_field(scout::testing::pack(scout::testing::unpack(real)), 0, 14, false, kWrong);
       },
       "its local header gives another CRC-32 or other sizes"},
      {"a 1 KiB junk prefix",
       [](const std::string& real) { return scout::testing::pack(scout::testing::unpack(real), {.prefix = 1024}); },
       "starts at byte 1024, where the file begins"},
      {"an unreferenced 64 MiB record",
       [](const std::string& real) { return with_record(real, std::size_t{64} << 20); },
       "data/9999: a record no tensor uses"},
      {"64 MiB of bytes between two entries",
       [](const std::string& real) {
         return scout::testing::pack(scout::testing::unpack(real), {.gap = std::size_t{64} << 20});
       },
       "where the entry before it ends at"},
      {"Adam's params not numeric",
       [](const std::string& real) {
         // The first parameter key (an address: "0x..." from LibTorch 1.x, decimal digits from
         // 2.x), which params/i and the state share through the memo, made letters in data.pkl
         // and in the state's class stub alike. A key is the first BINUNICODE string that is one.
         ZipFile zip = scout::testing::unpack(real);
         const std::string& pickle = scout::testing::entry(zip, "data.pkl");
         const auto is_key = [](const std::string& text) {
           const bool hex = text.size() > 2 && text.rfind("0x", 0) == 0;
           return hex || (text.size() >= 8 && text.find_first_not_of("0123456789") == std::string::npos);
         };
         std::string key;
         for (std::size_t at = 5; at < pickle.size() && key.empty(); ++at) {
           if (pickle[at - 5] != 'X') continue;
           const std::size_t length = scout::testing::le32(pickle, at - 4);
           if (length > 0 && length <= 20 && at + length <= pickle.size() && is_key(pickle.substr(at, length)))
             key = pickle.substr(at, length);
         }
         if (key.empty()) throw std::runtime_error("no parameter key");
         const std::string letters = "0x" + std::string(key.size() - 2, 'z');
         for (auto& [name, bytes] : zip.entries)
           for (std::size_t k = bytes.find(key); k != std::string::npos; k = bytes.find(key, k + 1))
             bytes.replace(k, key.size(), letters);
         return scout::testing::pack(zip);
       },
       "expected a parameter key (an address"},
      {"NaN in Adam's betas",
       [](const std::string& real) {
         Parts p = parts_of(real);
         p.options().betas(std::make_tuple(std::nan(""), 0.999));
         return p.write();
       },
       "betas: expected two numbers in [0, 1), got (nan, 0.999)"},
      {"Adam's amsgrad true",
       [](const std::string& real) {
         Parts p = parts_of(real);
         p.options().amsgrad(true);
         return p.write();
       },
       "amsgrad: expected false"},
      {"an infinite learning rate",
       [](const std::string& real) {
         Parts p = parts_of(real);
         p.options().lr(INFINITY);
         return p.write();
       },
       "lr: expected a finite number > 0"},
  };
}

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
      const std::string bytes = c.make(real_);
      const Outcome o = run_isolated([&] { open_and_resume(bytes, "hostile.pt"); });
      expect_refused(c.kind, o, "hostile.pt", c.expected);
    }
  }
  std::string real_;
};

// Scout's own files load, as written and through the replica of its writer, in a child whose
// peak memory is printed beside the refusals' for comparison.
TEST_F(HostileCheckpoints, TheWritersOwnFilesLoad) {
  const std::string model = read_bytes(fs::path(SCOUT_SOURCE_DIR) / "models/mnist.pt");
  struct Own {
    std::string kind, bytes;
    bool resume;  // a checkpoint (weights and Adam), or a model file (weights only)
  };
  for (const Own& own : std::vector<Own>{{"Scout's checkpoint, resumed", real_, true},
                                         {"the writer's replica, resumed", parts_of(real_).write(), true},
                                         {"models/mnist.pt, its networks built", model, false}}) {
    const auto& [kind, bytes, resume] = own;
    const Outcome o = run_isolated([&] {
      if (resume) return open_and_resume(bytes, "f.pt");
      load_agent(open_checkpoint_bytes(bytes, "f.pt"));
    });
    std::printf("%-52s %7ld KiB peak %6.0f ms  %s\n", kind.c_str(), o.peak_kib, o.seconds * 1000, o.message.c_str());
    EXPECT_EQ(o.status, 0) << kind << ": " << o.message;
  }
}

TEST_F(HostileCheckpoints, NestingUndeclaredAttributesAndDeepJsonAreRefused) { run_cases(pickle_cases()); }

TEST_F(HostileCheckpoints, TensorsOtherThanTheWritersAreRefused) { run_cases(tensor_cases()); }

TEST_F(HostileCheckpoints, LyingZipsAndAdamStatesAreRefused) { run_cases(zip_and_adam_cases()); }

// --- Unbounded inputs ---------------------------------------------------------------------------

// A 3 GiB sparse file and a FIFO as checkpoints: refused from what they are, before a byte is
// read (the FIFO without blocking in open(): the child's 60 s alarm would end a blocked one).
TEST_F(HostileCheckpoints, OversizedAndNonRegularFilesAreRefusedBeforeReading) {
  const fs::path sparse = temp_.path() / "sparse.pt", fifo = temp_.path() / "fifo.pt";
  std::filesystem::resize_file(fs::path(temp_.write("sparse.pt", "")), std::uintmax_t{3} << 30);
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
  // run folder whose checkpoint.pt links to it).
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
            {"export", {"export", file.string(), "--out", (out / "model.pt").string(), "--overwrite"}, file.string()},
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
  const std::vector<HostileCase> all_pickles = pickle_cases(), all_tensors = tensor_cases();
  const std::vector<HostileCase> kinds = {all_pickles[1], all_tensors[0], all_tensors[6]};
  std::vector<std::pair<std::string, fs::path>> files;
  for (const HostileCase& c : kinds)
    files.emplace_back(c.kind, temp_.write(c.kind.substr(0, 12) + ".pt", c.make(real_)));
  const fs::path sparse = temp_.path() / "sparse.pt";
  std::filesystem::resize_file(fs::path(temp_.write("sparse.pt", "")), std::uintmax_t{3} << 30);
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
  const fs::path model = fs::path(SCOUT_SOURCE_DIR) / "models/mnist.pt";
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
