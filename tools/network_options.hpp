#pragma once
// The training settings' options that `scout train` and `scout bench train` share, made from
// learn::train_settings() (the schema table in learn/train_config.cpp: one row per setting gives
// its option, help, default, value check and what a resume does with it); and --precision for
// the commands that run a trained model (run, eval, report), with what each says about it.
#include <map>
#include <string>

#include "agent/config.hpp"
#include "learn/train_config.hpp"

namespace CLI {
class App;
}

namespace scout::tools {

/// The training settings a command line gave, one option per row of learn::train_settings().
class SettingOptions {
 public:
  /// Adds an option for every setting `scout train` takes (`bench`: those `scout bench train`
  /// takes), each checked by its row (a bad value is a usage error with the row's message).
  void add_to(CLI::App& cmd, bool bench);
  /// Whether the command line gave this setting (by its JSON key, e.g. "rollouts").
  bool given(const learn::TrainSetting& setting) const;
  bool given(std::string_view key) const;
  /// `base` with every setting the command line gave set (checked by the options already).
  learn::TrainConfig applied_to(const learn::TrainConfig& base) const;
  /// The networks' arithmetic asked for, as given ("auto" when not).
  std::string precision() const;
  /// With `auto`: prints what it chose and why, in one line on stderr; with bf16 where it is
  /// emulated, a warning. Called once the command's checks have passed, so that a refusal stays
  /// one line.
  void announce_precision() const;

 private:
  const CLI::App* cmd_ = nullptr;
  std::map<std::string, std::string> texts_;  ///< by JSON key, as given
  std::map<std::string, bool> flags_;
};

/// Names a setting by its option in learn::TrainConfig::validate's messages ("--rollouts").
std::string setting_option(const learn::TrainSetting& setting);

/// Prints learn::auto_precision().note on stderr when `requested` is "auto", and a warning when bf16
/// is asked for on a CPU that would emulate it.
void announce_auto_precision(const std::string& requested);

/// --precision's choices, "auto, bf16, fp32" (its messages).
std::string precision_choices();

/// --precision for the commands that run a trained model (run, eval, report): default auto, this
/// CPU's best arithmetic, whatever the model was trained in.
void add_model_precision_option(CLI::App& cmd, std::string& precision);

/// One line on stderr saying what a model runs in here: with `auto`, what it chose and why (and
/// that the model was trained in the other one when it differs); with bf16 asked on a CPU without
/// native bf16, that it is emulated and several times slower than fp32. Nothing otherwise.
void announce_model_precision(const std::string& requested, agent::Precision trained);

}  // namespace scout::tools
