#include "tools/network_options.hpp"

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <cstdio>

#include "learn/auto_precision.hpp"
#include "learn/train_config.hpp"
#include "tools/parsing.hpp"

namespace scout::tools {

std::string precision_choices() { return "auto, bf16, fp32"; }

namespace {

// --precision's check beyond its row's: bf16 only where it can run at all.
std::string bf16_problem(const std::string& text) {
  if (agent::parse_precision(text) != agent::Precision::BFloat16) return {};
  const std::string why = agent::bf16_unavailable();
  return why.empty() ? std::string() : "bf16: " + why;
}

CLI::Validator precision_validator() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        try {
          agent::parse_precision(text);
        } catch (const std::invalid_argument&) {
          return "expected one of " + precision_choices() + ", got '" + one_line(text) + "'";
        }
        return bf16_problem(text);
      },
      "PRECISION");
}

// A setting's check: its row's (learn::set_setting), and bf16 only where it can run.
CLI::Validator setting_validator(const learn::TrainSetting& setting) {
  return CLI::Validator(
      [&setting](std::string& text) -> std::string {
        learn::TrainConfig scratch;
        try {
          learn::set_setting(scratch, setting, text);
        } catch (const InputError& e) {
          return e.what();
        }
        return setting.type == learn::SettingType::Precision ? bf16_problem(text) : std::string();
      },
      learn::setting_value_name(setting));
}

const char* type_name(const learn::TrainSetting& setting) {
  switch (setting.type) {
    case learn::SettingType::Integer:
      return "INT";
    case learn::SettingType::Number:
      return "FLOAT";
    default:
      return "TEXT";
  }
}

}  // namespace

void SettingOptions::add_to(CLI::App& cmd, bool bench) {
  cmd_ = &cmd;
  const learn::TrainConfig defaults;  // the library's defaults are the command's
  for (const learn::TrainSetting& s : learn::train_settings()) {
    if (s.commands == learn::SettingCommands::None || (bench && s.commands != learn::SettingCommands::TrainAndBench))
      continue;
    const std::string key = learn::setting_key(s);
    if (s.type == learn::SettingType::Flag) {
      cmd.add_flag(std::string(s.option), flags_[key], learn::setting_help(s));
      continue;
    }
    CLI::Option* option = cmd.add_option(std::string(s.option), texts_[key], learn::setting_help(s));
    option->type_name(type_name(s))->check(setting_validator(s));
    if (s.shows_default) option->default_str(learn::setting_text(defaults, s));
  }
}

bool SettingOptions::given(const learn::TrainSetting& setting) const {
  if (setting.option.empty() || cmd_ == nullptr) return false;
  const CLI::Option* option = cmd_->get_option_no_throw(std::string(setting.option));
  return option != nullptr && option->count() > 0;
}

bool SettingOptions::given(std::string_view key) const { return given(learn::train_setting(key)); }

learn::TrainConfig SettingOptions::applied_to(const learn::TrainConfig& base) const {
  learn::TrainConfig config = base;
  for (const learn::TrainSetting& s : learn::train_settings()) {
    if (!given(s)) continue;
    const std::string key = learn::setting_key(s);
    learn::set_setting(config, s,
                       s.type == learn::SettingType::Flag ? (flags_.at(key) ? "on" : "off") : texts_.at(key));
  }
  return config;
}

std::string SettingOptions::precision() const { return given("precision") ? texts_.at("precision") : "auto"; }

void SettingOptions::announce_precision() const { announce_auto_precision(precision()); }

std::string setting_option(const learn::TrainSetting& setting) {
  return setting.option.empty() ? learn::setting_key(setting) : std::string(setting.option);
}

void announce_auto_precision(const std::string& requested) {
  // Training has no model yet: what it trains in is what it runs in.
  announce_model_precision(requested, learn::resolve_precision(agent::parse_precision(requested)));
}

void add_model_precision_option(CLI::App& cmd, std::string& precision) {
  precision = "auto";
  cmd.add_option("--precision", precision,
                 "Networks' arithmetic: auto (the faster on this CPU, measured once: bf16 only where it is native and "
                 "faster; whatever the model was trained in) | bf16 | fp32")
      ->capture_default_str()
      ->check(precision_validator());
}

void announce_model_precision(const std::string& requested, agent::Precision trained) {
  const agent::Precision asked = agent::parse_precision(requested);  // checked by the option
  const agent::Precision used = learn::resolve_precision(asked);
  if (asked == agent::Precision::Auto) {
    std::string line = learn::auto_precision().note;
    if (used != trained) line += fmt::format("; the model was trained in {}", agent::to_string(trained));
    std::fprintf(stderr, "%s\n", line.c_str());
  } else if (used == agent::Precision::BFloat16 && !agent::native_bf16().any()) {
    std::fprintf(stderr,
                 "precision: bf16 as asked, emulated: this CPU has no native bf16, so the networks run several "
                 "times slower than in fp32 (--precision auto picks fp32 here)\n");
  }
}

}  // namespace scout::tools
