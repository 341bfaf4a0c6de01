// `scout report` end to end on the EvalRun fixture's tiny model (real Box2D, OSMesa, LibTorch and
// matplotlib): the folder's files, numbers that agree with the evaluation and with each other, an
// evaluation found beside the model and not repeated, and bad inputs refused with one line.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/eval_run_fixture.hpp"

namespace scout::testing::report_command_tests {

using namespace scout::testing::eval_run_support;

// `scout ARGS` with an environment variable set (the shell runs the command line).
Result scout_with_env(const std::string& assignment, const std::string& args) {
  return scout::testing::run_cli(assignment + " " + SCOUT_BINARY, args);
}

std::string read_text(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// The report's history, row by row, against the run's metrics.csv (mode, epoch and the
// validation figures as the file prints them).
void expect_history_is_the_runs_metrics(const json& history, const std::string& metrics_csv) {
  std::istringstream lines(read_text(metrics_csv));
  std::string line;
  std::getline(lines, line);  // the header
  std::size_t row = 0;
  for (; std::getline(lines, line); ++row) {
    std::vector<std::string> cells;
    std::istringstream in(line);
    for (std::string cell; std::getline(in, cell, ',');) cells.push_back(cell);
    ASSERT_LT(row, history.size()) << line;
    const json& h = history[row];
    EXPECT_EQ(h["mode"], cells.at(0)) << line;
    EXPECT_EQ(h["epoch"], std::stoi(cells.at(1))) << line;
    EXPECT_NEAR(h["validation_accuracy"].get<double>(), std::stod(cells.at(5)), 1e-6) << line;
    EXPECT_NEAR(h["validation_full_image"].get<double>(), std::stod(cells.at(11)), 1e-6) << line;
    // The gradient norm where the run measured it (six significant digits in the file).
    if (cells.size() > 12 && !cells.at(12).empty()) {
      EXPECT_NEAR(h["gradient_norm"].get<double>() / std::stod(cells.at(12)), 1.0, 1e-5) << line;
    }
  }
  EXPECT_EQ(row, history.size());
}

TEST_F(EvalRun, ReportEvaluatesAndDrawsTheTableAndFigures) {
  const Result r = scout("report " + path("run") + " --out " + path("report") + test_data() +
                         " --runs 2 --sweep-digits 9 --sweep-runs 1 --episodes 4 --seed 4");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("evaluating on 9 digits, 2 runs"), std::string::npos) << r.output;
  for (const char* file : {"REPORT.md", "report-data.json", "eval.json", "manifest.json", "accuracy_vs_epochs.png",
                           "confusion.png", "episodes.png", "budget.png"})
    EXPECT_TRUE(fs::is_regular_file(path("report") + "/" + file)) << file;
  EXPECT_FALSE(fs::exists(path("report") + "/.plot.log"));

  const json eval = read_json(path("report") + "/eval.json");
  const json data = read_json(path("report") + "/report-data.json");
  EXPECT_EQ(eval["runs"], 2);
  EXPECT_EQ(eval["images"], kTestImages);
  EXPECT_EQ(data["model"]["eval"]["accuracy"], eval["accuracy"]);
  // The history is the checkpoint's: one epoch of each mode, with its validation baselines.
  ASSERT_EQ(data["model"]["history"].size(), 3u);
  for (const json& row : data["model"]["history"]) {
    for (const char* key :
         {"validation_accuracy", "validation_iid", "validation_goals_only", "validation_full_image"}) {
      if (std::string(key) == "validation_goals_only" && row["mode"] == "i") {
        EXPECT_TRUE(row[key].is_null()) << "goals only before mode (ii)";
        continue;
      }
      ASSERT_TRUE(row[key].is_number()) << key << " in mode " << row["mode"];
      EXPECT_GE(row[key].get<double>(), 0.0);
      EXPECT_LE(row[key].get<double>(), 1.0);
    }
  }
  // Ten sweep points; a bigger window reveals more of the floor on the same digits.
  const json& points = data["sweep"]["points"];
  ASSERT_EQ(points.size(), 10u);
  EXPECT_EQ(points[0]["patch_px"], 2);
  EXPECT_EQ(points[4]["patch_px"], 10);
  EXPECT_LT(points[0]["revealed_fraction"].get<double>(), points[4]["revealed_fraction"].get<double>());
  // Four episodes, the right ones first, each with what the picture needs.
  ASSERT_EQ(data["episodes"].size(), 4u);
  for (const json& e : data["episodes"]) {
    EXPECT_EQ(e["floor"].size(), static_cast<std::size_t>(kSide * kSide));
    EXPECT_EQ(e["seen"].size(), static_cast<std::size_t>(kSide * kSide));
    EXPECT_EQ(e["goals"].size(), 2u);  // E = 2
    EXPECT_EQ(e["path"].size(), 5u);   // the start and E x T = 4 moves
    EXPECT_EQ(e["goal_map"].size(), static_cast<std::size_t>(kSide * kSide));
  }
  expect_history_is_the_runs_metrics(data["model"]["history"], path("run") + "/metrics.csv");
  // A budget point is what scout eval gives in that world: m = 4 (points[1]) on the same 9
  // digits, 1 run, seed 4.
  temp_->write("world-m4.yaml", "floor: {dataset: " + path("data") +
                                    ", split: test, index: random}\n"
                                    "camera: {patch_px: 4}\n"
                                    "task: {episodes: 2, steps: 2}\n");
  const Result at_m4 = scout("eval --checkpoint " + path("run") + test_data() + " --world " + path("world-m4.yaml") +
                             " --runs 1 --seed 4 --json " + path("m4-eval.json"));
  ASSERT_EQ(at_m4.status, 0) << at_m4.output;
  ASSERT_EQ(points[1]["patch_px"], 4);
  EXPECT_EQ(points[1]["accuracy"], read_json(path("m4-eval.json"))["accuracy"]["mean"]);
  const std::string report = read_text(path("report") + "/REPORT.md");
  EXPECT_NE(report.find("94.61 ± 0.17 %"), std::string::npos);
  EXPECT_NE(report.find("](budget.png)"), std::string::npos);
  EXPECT_NE(report.find("scout train " + world()), std::string::npos) << "the training command is missing";
}

TEST_F(EvalRun, ReportUsesTheEvaluationBesideTheModel) {
  const Result e =
      scout("eval --checkpoint " + path("run") + test_data() + " --runs 2 --json " + path("run") + "/test-eval.json");
  ASSERT_EQ(e.status, 0) << e.output;
  // A model trained in several runs lists the earlier runs' manifests under "lineage" (as
  // models/mnist-manifest.json does): their commands come before the run's own.
  const std::string manifest_file = path("run") + "/manifest.json";
  const std::string manifest_text = read_text(manifest_file);
  json manifest = json::parse(manifest_text);
  manifest["lineage"] =
      json::array({{{"command_line", {"scout", "train", "first.yaml", "--out", "runs/first"}},
                    {"resumed", {{{"command_line", {"scout", "train", "--resume", "runs/first"}}}}}}});
  manifest["lineage_note"] = "runs/first was exported to first.safetensors";
  std::ofstream(manifest_file, std::ios::binary | std::ios::trunc) << manifest.dump();
  const Result r =
      scout("report " + path("run") + " --out " + path("beside") + test_data() + " --sweep-digits 0 --episodes 0");
  std::ofstream(manifest_file, std::ios::binary | std::ios::trunc) << manifest_text;
  fs::remove(path("run") + "/test-eval.json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output.find("evaluating"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(path("beside") + "/eval.json"));
  EXPECT_FALSE(fs::exists(path("beside") + "/budget.png"));
  const std::string report = read_text(path("beside") + "/REPORT.md");
  EXPECT_NE(report.find("scout eval --checkpoint " + path("run")), std::string::npos) << report;
  const std::size_t first = report.find(
      "# runs/first was exported to first.safetensors\nscout train first.yaml --out runs/first\nscout train --resume "
      "runs/first\n");
  const std::size_t own = report.find("scout train " + world());
  ASSERT_NE(first, std::string::npos) << report;
  ASSERT_NE(own, std::string::npos) << report;
  EXPECT_LT(first, own) << "the earlier run's commands come first";
}

// A compared model's row carries its own evaluation's figures, and its history (read from the
// model the evaluation names) is drawn beside this model's: mode (i) only, one epoch.
TEST_F(EvalRun, ReportComparesAnotherModelsRowAndCurve) {
  const Result other =
      scout("eval --checkpoint " + checkpoint("run_i") + test_data() + " --runs 2 --json " + path("mode-i-eval.json"));
  ASSERT_EQ(other.status, 0) << other.output;
  const Result r =
      scout("report " + path("run") + " --out " + path("compared") + test_data() +
            " --runs 2 --sweep-digits 0 --episodes 0 --compare \"mode i only=" + path("mode-i-eval.json") + "\"");
  ASSERT_EQ(r.status, 0) << r.output;
  const json evaluated = read_json(path("mode-i-eval.json"));
  const json data = read_json(path("compared") + "/report-data.json");
  ASSERT_EQ(data["compare"].size(), 1u);
  const json& row = data["compare"][0];
  EXPECT_EQ(row["label"], "mode i only");
  EXPECT_EQ(row["eval"]["accuracy"], evaluated["accuracy"]);
  EXPECT_EQ(row["eval"]["top2"], evaluated["top2"]);
  ASSERT_EQ(row["history"].size(), 1u);
  EXPECT_EQ(row["history"][0]["mode"], "i");
  // The mode (i) run trained the same first epoch as the full run, from the same seed.
  EXPECT_EQ(row["history"][0]["validation_accuracy"], data["model"]["history"][0]["validation_accuracy"]);
  const std::string report = read_text(path("compared") + "/REPORT.md");
  const std::string mean = fmt::format("{:.2f} ± {:.2f} %", 100 * evaluated["accuracy"]["mean"].get<double>(),
                                       100 * evaluated["accuracy"]["ci95"].get<double>());
  const std::size_t line = report.find("| mode i only |");
  ASSERT_NE(line, std::string::npos) << report;
  EXPECT_NE(report.substr(line, report.find('\n', line) - line).find(mean), std::string::npos) << report;
  EXPECT_TRUE(fs::is_regular_file(path("compared") + "/accuracy_vs_epochs.png"));
}

// A scenario agent with learned goals (a row of report-data.json's scenario_agents): its goals-only
// baseline measured, as `scout eval` of the same agent in the same world (`eval`) gives it.
void expect_goals_only_baseline_as_eval_gives_it(const json& row, const json& eval) {
  EXPECT_EQ(row.at("accuracy"), eval["accuracy"]["mean"]);
  ASSERT_TRUE(row.at("goals_only_accuracy").is_number()) << row.dump();
  EXPECT_EQ(row.at("goals_only_accuracy"), eval["baselines"]["goals_only"]);
  EXPECT_EQ(row.at("goals_only_ci95"), eval["baselines"]["goals_only_ci95"]);
  EXPECT_EQ(row.at("iid_accuracy"), eval["baselines"]["iid"]);
}

// --scenarios: the robustness table, the model in its own world and in each scenario world; a row
// is what scout eval gives in that world on the same digits, runs and seed, stalled moves included.
// --scenario-agent: another agent in its scenario world beside the model there, the same way.
// --sweep-compare: another model's E x T curve beside the model's.
TEST_F(EvalRun, ReportMeasuresTheModelInScenarioWorlds) {
  const std::string world_text = "floor: {dataset: " + path("data") +
                                 ", split: test, index: random}\ncamera: {patch_px: 3}\ntask: {episodes: 2, "
                                 "steps: 2}\n";
  temp_->write("odometry.yaml", world_text + "motion: {scale_sd: 0.25, heading_sd_deg: 15, pose: odometry}\n");
  temp_->write("boxes.yaml", world_text + "obstacles: {random_boxes: 2, random_box_min_px: 2, random_box_max_px: 3}\n");
  const Result r = scout("report " + path("run") + " --out " + path("robust") + test_data() +
                         " --runs 1 --sweep-digits 3 --sweep-runs 1 --episodes 0 --seed 6 --scenario-digits 9 "
                         "--scenario-runs 2 --sweep-compare \"mode i=" +
                         checkpoint("run_i") + "\" --scenario-agent " + path("boxes.yaml") + "=" + checkpoint("run_i") +
                         " --scenario-agent " + path("boxes.yaml") + "=" + path("run") + " --scenarios " +
                         path("odometry.yaml") + " " + path("boxes.yaml"));
  ASSERT_EQ(r.status, 0) << r.output;
  const json data = read_json(path("robust") + "/report-data.json");
  const json& rows = data["robustness"]["rows"];
  ASSERT_EQ(rows.size(), 3u) << data["robustness"].dump();
  EXPECT_EQ(rows[0]["world"], "the model's world");
  EXPECT_EQ(rows[1]["world"], "odometry");
  EXPECT_EQ(rows[2]["world"], "boxes");
  EXPECT_EQ(data["robustness"]["digits"], 9);
  for (const json& row : rows) {
    EXPECT_GE(row["accuracy"].get<double>(), 0.0);
    EXPECT_LE(row["accuracy"].get<double>(), 1.0);
    EXPECT_GT(row["revealed_fraction"].get<double>(), 0.0);
  }
  const Result direct = scout("eval --checkpoint " + path("run") + test_data() + " --world " + path("boxes.yaml") +
                              " --limit 9 --runs 2 --seed 6 --json " + path("boxes-eval.json"));
  ASSERT_EQ(direct.status, 0) << direct.output;
  const json boxes = read_json(path("boxes-eval.json"));
  EXPECT_EQ(rows[2]["accuracy"], boxes["accuracy"]["mean"]);
  EXPECT_EQ(rows[2]["stalled_moves"], boxes["stalled_moves_per_rollout"]);
  const Result agent_direct =
      scout("eval --checkpoint " + checkpoint("run_i") + test_data() + " --world " + path("boxes.yaml") +
            " --limit 9 --runs 2 --seed 6 --json " + path("agent-eval.json"));
  ASSERT_EQ(agent_direct.status, 0) << agent_direct.output;
  const json agent = read_json(path("agent-eval.json"));
  ASSERT_EQ(data.at("scenario_agents").at("rows").size(), 2u) << data.dump();
  const json& agent_row = data["scenario_agents"]["rows"][0];
  EXPECT_EQ(agent_row.at("world"), "boxes");
  EXPECT_EQ(agent_row.at("accuracy"), agent["accuracy"]["mean"]);
  EXPECT_EQ(agent_row.at("stalled_moves"), agent["stalled_moves_per_rollout"]);
  EXPECT_EQ(agent_row.at("revealed_fraction"), agent["revealed_fraction"]);
  // Its baselines in its world, as scout eval gives them (min(5, R) = 2 baseline runs each).
  EXPECT_EQ(agent_row.at("baseline_runs"), 2);
  EXPECT_EQ(agent_row.at("iid_accuracy"), agent["baselines"]["iid"]);
  EXPECT_EQ(agent_row.at("iid_ci95"), agent["baselines"]["iid_ci95"]);
  EXPECT_TRUE(agent_row.at("goals_only_accuracy").is_null());  // mode (i) learns no goals
  EXPECT_TRUE(agent["baselines"]["goals_only"].is_null());
  EXPECT_EQ(agent_row.at("model_accuracy"), boxes["accuracy"]["mean"]);
  EXPECT_EQ(agent_row.at("model_stalled_moves"), boxes["stalled_moves_per_rollout"]);
  EXPECT_EQ(agent_row.at("model_revealed_fraction"), boxes["revealed_fraction"]);
  expect_goals_only_baseline_as_eval_gives_it(data["scenario_agents"]["rows"][1], boxes);
  const json& compared = data["sweep"]["compared"];
  ASSERT_EQ(compared.size(), 1u);
  EXPECT_EQ(compared[0]["label"], "mode i");
  ASSERT_EQ(compared[0]["points"].size(), 5u) << compared.dump();  // E = 1, 2, 4, 6, 8
  for (const json& p : compared[0]["points"]) EXPECT_EQ(p["kind"], "moves");
  const std::string report = read_text(path("robust") + "/REPORT.md");
  EXPECT_NE(report.find("## Robustness in the scenario worlds"), std::string::npos) << report;
  EXPECT_NE(report.find("| odometry | "), std::string::npos) << report;
  EXPECT_NE(report.find("## Agents trained for a scenario world"), std::string::npos) << report;
  // An agent given without its world is refused before any work, naming the option.
  const Result no_world = scout("report " + path("run") + " --out " + path("robust-bad") + test_data() +
                                " --scenario-agent " + checkpoint("run_i"));
  EXPECT_EQ(no_world.status, 1) << no_world.output;
  EXPECT_NE(no_world.output.find("--scenario-agent: expected WORLD.yaml=MODEL"), std::string::npos) << no_world.output;
  // A world file that does not load is refused before any work, naming it.
  temp_->write("bad.yaml", world_text + "motion: {scale_sd: 2}\n");
  const Result bad = scout("report " + path("run") + " --out " + path("robust-bad") + test_data() + " --scenarios " +
                           path("bad.yaml"));
  EXPECT_EQ(bad.status, 1) << bad.output;
  EXPECT_EQ(bad.output.rfind("scout: error: " + path("bad.yaml") + ":", 0), 0u) << bad.output;
  EXPECT_NE(bad.output.find("motion.scale_sd"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(path("robust-bad")));
}

TEST_F(EvalRun, ReportRefusesBadInputsWithOneLine) {
  const Result other =
      scout("eval --checkpoint " + checkpoint("run_i") + test_data() + " --runs 1 --json " + path("other-eval.json"));
  ASSERT_EQ(other.status, 0) << other.output;
  // The right model evaluated on other digits (its validation split) is no test-set figure.
  const Result on_validation = scout(
      "eval --checkpoint " + path("run") + " --images " + path("data/validation-images-idx3-ubyte") + " --labels " +
      path("data/validation-labels-idx1-ubyte") + " --runs 1 --json " + path("run") + "/validation-eval.json");
  ASSERT_EQ(on_validation.status, 0) << on_validation.output;
  struct Case {
    std::string args, message_start;
  };
  const Case cases[] = {
      {"--eval " + path("other-eval.json"),
       "scout: error: --eval: " + path("other-eval.json") + ": manifest.checkpoint_sha256: expected "},
      {"--compare nolabel", "scout: error: --compare: expected LABEL=EVAL.json, got \"nolabel\""},
      {"--eval " + path("run") + "/validation-eval.json" + test_data(),
       "scout: error: --eval: " + path("run") +
           "/validation-eval.json: manifest.data_sha256: expected an evaluation "
           "of " +
           path("data/t10k-images-idx3-ubyte")},
      {"--compare x=" + path("missing.json"), "scout: error: --compare: " + path("missing.json") + ": cannot open"},
      {"--images " + path("data/t10k-images-idx3-ubyte"),
       "scout: error: --images and --labels: expected both or neither"},
  };
  for (const Case& c : cases) {
    const Result r = scout("report " + path("run") + " --out " + path("refused") + " " + c.args);
    EXPECT_EQ(r.status, 1) << c.args << "\n" << r.output;
    EXPECT_EQ(r.output.rfind(c.message_start, 0), 0u) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(fs::exists(path("refused")));
  }
  fs::remove(path("run") + "/validation-eval.json");
  const Result no_script = scout_with_env("SCOUT_REPORT_SCRIPT=" + path("nope.py"),
                                          "report " + path("run") + " --out " + path("refused") + test_data());
  EXPECT_EQ(no_script.status, 1) << no_script.output;
  EXPECT_NE(no_script.output.find("the report's plotting script is missing"), std::string::npos) << no_script.output;
}

}  // namespace scout::testing::report_command_tests
