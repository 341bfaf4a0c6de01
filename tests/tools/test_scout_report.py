"""scout report's plotting script (tools/report/scout_report.py) on report data built here: the
figures are real PNGs of the expected sizes, REPORT.md carries the paper's row, the model's
figures as the data give them and the error shares computed from them, and bad data is one line
on stderr with exit status 1. (scout report itself, end to end, is tested in test_report_command.)"""
import json
import os
import subprocess
import sys

import matplotlib.image as mpimg
import numpy as np
import pytest

SOURCE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCRIPT = os.path.join(SOURCE, "tools", "report", "scout_report.py")


def confusion(accuracy):
    m = np.full((10, 10), (1 - accuracy) / 9)
    np.fill_diagonal(m, accuracy)
    m[3, 3], m[3, 5] = accuracy - 0.05, m[3, 5] + 0.05  # class 3 the weakest
    return m.tolist()


def report_data():
    rng = np.random.default_rng(0)
    history = []
    for mode, epochs, level in (("full", 2, 0.98), ("i", 2, 0.85), ("ii", 3, 0.93), ("iii", 4, 0.96)):
        for e in range(1, epochs + 1):
            history.append({"mode": mode, "epoch": e, "validation_accuracy": level + 0.001 * e,
                            "validation_iid": 0.85, "validation_goals_only": 0.93 if mode == "iii" else 0.9,
                            "validation_full_image": 0.99, "seconds": 10.0, "learning_rate": 0.001})
    history[0]["validation_iid"] = None  # rows written before the baselines were measured
    ev = {"accuracy": {"mean": 0.97, "ci95": 0.002}, "top2": {"mean": 0.99, "ci95": 0.001},
          "confusion": confusion(0.97), "baselines": {"iid": 0.88, "goals_only": 0.94},
          "full_image": 0.992, "greedy": 0.9, "runs": 20, "images": 10000, "precision": "bf16",
          "revealed_fraction": 0.42, "data": "t10k-images-idx3-ubyte"}
    points = []
    for m, frac, acc in ((2, 0.1, 0.6), (4, 0.25, 0.85), (6, 0.42, 0.97), (8, 0.6, 0.98)):
        points.append({"kind": "patch", "patch_px": m, "episodes": 4, "steps": 5, "accuracy": acc, "ci95": 0.01,
                       "revealed_fraction": frac})
    for e, frac, acc in ((1, 0.15, 0.7), (2, 0.25, 0.88), (4, 0.42, 0.97)):
        points.append({"kind": "moves", "patch_px": 6, "episodes": e, "steps": 5, "accuracy": acc, "ci95": 0.01,
                       "revealed_fraction": frac})
    episodes = []
    for k, (label, prediction) in enumerate(((1, 1), (7, 7), (4, 9), (3, 5))):
        floor = (rng.random(784) * 255).astype(int).tolist()
        seen = (rng.random(784) < 0.4).astype(int).tolist()
        p = np.full(10, 0.02)
        p[prediction] = 0.82
        episodes.append({"index": k, "label": label, "prediction": prediction, "probabilities": p.tolist(),
                         "width": 28, "height": 28, "patch_px": 6, "floor": floor, "seen": seen,
                         "path": [[10, 10], [12, 10], [12, 12]], "goals": [[12, 10], [20, 20]],
                         "goal_map": (np.ones(784) / 784).tolist(), "goal_map_episode": 4})
    return {
        "command": "scout report models/x.safetensors --out r", "cpu": "a test CPU", "seconds": 12.0,
        "paper": {"accuracy": 94.61, "ci95": 0.17, "top2": 98.30, "full_image": 94.92, "transfer": 95.19,
                  "revealed_fraction": 0.41,
                  "glimpse_models": [
                      {"source": "RAM (Mnih et al. 2014)", "accuracy": 98.46, "glimpses": 4, "side": 8,
                       "revealed_fraction": 256 / 784},
                      {"source": "RAM (Mnih et al. 2014)", "accuracy": 98.88, "glimpses": 6, "side": 8,
                       "revealed_fraction": 384 / 784}]},
        "model": {"label": "Scout: x.safetensors", "path": "models/x.safetensors", "eval": ev, "eval_source": "x-test-eval.json",
                  "eval_command": "scout eval --checkpoint models/x.safetensors", "train_commands": ["scout train w.yaml"],
                  "history": history, "revealed_fraction": 0.42},
        "compare": [{"label": "Paper-faithful run", "eval": dict(ev, accuracy={"mean": 0.93, "ci95": 0.003}),
                     "eval_source": "f.json", "eval_command": "", "train_commands": []}],
        "sweep": {"digits": 500, "runs": 2, "seed": 1, "points": points, "compared": [
            {"label": "the paper's agent", "points": [
                {"kind": "moves", "patch_px": 6, "episodes": e, "steps": 5, "accuracy": acc, "ci95": 0.01,
                 "revealed_fraction": frac} for e, frac, acc in ((2, 0.24, 0.85), (4, 0.4, 0.95))]}]},
        "episode_seed": 1, "episodes": episodes,
    }


def run(tmp_path, data):
    data_file = tmp_path / "report-data.json"
    data_file.write_text(json.dumps(data))
    out = tmp_path / "out"
    out.mkdir(exist_ok=True)
    return subprocess.run([sys.executable, SCRIPT, str(data_file), str(out)], capture_output=True, text=True), out


def test_the_figures_and_report_are_written(tmp_path):
    result, out = run(tmp_path, report_data())
    assert result.returncode == 0, result.stderr
    for name, min_w, min_h in (("accuracy_vs_epochs.png", 600, 300), ("confusion.png", 800, 350),
                               ("episodes.png", 600, 800), ("budget.png", 500, 300)):
        image = mpimg.imread(out / name)
        assert image.shape[1] >= min_w and image.shape[0] >= min_h, (name, image.shape)
        assert image[..., :3].std() > 0.05, f"{name} is blank"
    text = (out / "REPORT.md").read_text()
    assert "94.61 ± 0.17 %" in text  # the paper's row
    assert "97.00 ± 0.20 %" in text  # the model's accuracy, as the data give it
    assert "| Paper-faithful run | 93.00 ± 0.30 %" in text
    assert "scout train w.yaml" in text
    # i.i.d. errors 12 %, goals only 6 %, agent 3 %: goals remove 50 %, actions another 25 %.
    assert "12.00 % errors; learned goals remove 50 % of them and learned actions another 25 %" in text
    for figure in ("accuracy_vs_epochs.png", "confusion.png", "episodes.png", "budget.png"):
        assert f"]({figure})" in text
    # Per-class accuracy from the confusion matrix's diagonal (class 3 is 92.0).
    assert "| accuracy | 97.0 | 97.0 | 97.0 | 92.0 |" in text
    # The compared budget curve and the glimpse models' published points, as another task's.
    assert "the paper's agent at the same budgets: 2 × 5: 85.00 %, 4 × 5: 95.00 %." in text
    assert "RAM (Mnih et al. 2014), 4 glimpses of 8 × 8: 98.46 % (at most 33 % of the pixels)" in text
    assert "another task" in text


def test_an_agent_without_learned_actions_is_credited_with_its_goals_only(tmp_path):
    data = report_data()
    data["model"]["eval"]["learned"] = {"goals": True, "actions": False}
    data["model"]["eval"]["accuracy"] = {"mean": 0.94, "ci95": 0.002}  # its own goals-only baseline
    result, out = run(tmp_path, data)
    assert result.returncode == 0, result.stderr
    text = (out / "REPORT.md").read_text()
    # i.i.d. errors 12 %, the agent 6 %: its goals remove 50 %, and no action share is claimed.
    assert "12.00 % errors; learned goals remove 50 % of them. This agent's axes are drawn i.i.d." in text
    assert "learned actions another" not in text


def test_the_robustness_table_lists_each_world_and_its_change(tmp_path):
    data = report_data()
    data["robustness"] = {"digits": 1000, "runs": 5, "seed": 7, "rows": [
        {"world": "the model's world", "file": "", "accuracy": 0.9602, "ci95": 0.0045, "revealed_fraction": 0.285},
        {"world": "odometry-strong", "file": "worlds/scenarios/odometry-strong.yaml", "accuracy": 0.7142,
         "ci95": 0.012, "revealed_fraction": 0.27}]}
    data["scenario_agents"] = {"digits": 1000, "runs": 5, "seed": 7, "rows": [
        {"world": "obstacles-random", "agent": "models/obstacles-random.safetensors", "accuracy": 0.95, "ci95": 0.004,
         "stalled_moves": 2.25, "model_accuracy": 0.93, "model_ci95": 0.006, "model_stalled_moves": 8.5}]}
    result, out = run(tmp_path, data)
    assert result.returncode == 0, result.stderr
    text = (out / "REPORT.md").read_text()
    assert "## Robustness in the scenario worlds" in text
    assert "first 1000 test digits, 5 stochastic run(s), seed 7" in text
    assert "| the model's world | 96.02 ± 0.45 % |  | 28.5 % |" in text
    assert "| odometry-strong | 71.42 ± 1.20 % | -24.60 points | 27.0 % |" in text
    assert "| obstacles-random | `models/obstacles-random.safetensors` | 95.00 ± 0.40 % | 2.25 | 93.00 ± 0.60 % | 8.50 |" in text
    assert "random moves" not in text  # a report made before the baselines were measured: no such columns
    # With the agent's baselines: random moves, goals only (none for an agent without learned goals)
    # and the floor seen, between its accuracy and its stalled moves.
    data["scenario_agents"]["rows"].append(
        {"world": "translated-60", "agent": "models/translated-60.safetensors", "accuracy": 0.91, "ci95": 0.01,
         "revealed_fraction": 0.123, "stalled_moves": 0.0, "baseline_runs": 5, "iid_accuracy": 0.3, "iid_ci95": 0.02,
         "goals_only_accuracy": 0.905, "goals_only_ci95": 0.011, "model_accuracy": 0.25, "model_ci95": 0.03,
         "model_revealed_fraction": 0.08, "model_stalled_moves": 0.0})
    for row in data["scenario_agents"]["rows"][:1]:
        row.update(revealed_fraction=0.3, baseline_runs=5, iid_accuracy=0.8, iid_ci95=0.01, goals_only_accuracy=None,
                   goals_only_ci95=None, model_revealed_fraction=0.29)
    result, out = run(tmp_path, data)
    assert result.returncode == 0, result.stderr
    text = (out / "REPORT.md").read_text()
    assert ("| world | agent | accuracy | random moves | goals only | floor seen | stalled moves | this model | "
            "its floor seen | its stalled moves |") in text
    assert ("| obstacles-random | `models/obstacles-random.safetensors` | 95.00 ± 0.40 % | 80.00 ± 1.00 % | - | 30.0 % "
            "| 2.25 | 93.00 ± 0.60 % | 29.0 % | 8.50 |") in text
    assert ("| translated-60 | `models/translated-60.safetensors` | 91.00 ± 1.00 % | 30.00 ± 2.00 % | "
            "90.50 ± 1.10 % | 12.3 % | 0.00 | 25.00 ± 3.00 % | 8.0 % | 0.00 |") in text
    assert "Robustness" not in run(tmp_path, report_data())[1].joinpath("REPORT.md").read_text()


def test_without_history_sweep_or_episodes_the_rest_is_still_drawn(tmp_path):
    data = report_data()
    data["model"]["history"] = []
    del data["sweep"]
    data["episodes"] = []
    result, out = run(tmp_path, data)
    assert result.returncode == 0, result.stderr
    assert (out / "confusion.png").exists()
    assert not (out / "budget.png").exists()
    assert "The model carries no training history." in (out / "REPORT.md").read_text()


@pytest.mark.parametrize("break_it, expect", [
    (lambda d: d.pop("model"), "missing field 'model'"),
    (lambda d: d["model"]["eval"].pop("confusion"), "missing field 'confusion'"),
    (lambda d: d["model"]["eval"].__setitem__("accuracy", "high"), "malformed report data"),
])
def test_bad_data_is_one_line_and_status_one(tmp_path, break_it, expect):
    data = report_data()
    break_it(data)
    result, _ = run(tmp_path, data)
    assert result.returncode == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert expect in lines[0]


def test_a_file_that_is_not_json_is_refused(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    (tmp_path / "o").mkdir()
    result = subprocess.run([sys.executable, SCRIPT, str(bad), str(tmp_path / "o")], capture_output=True, text=True)
    assert result.returncode == 1
    assert result.stderr.startswith(f"scout_report.py: {bad}:")
