#!/usr/bin/env python3
"""Draws `scout report`'s figures and writes its REPORT.md.

`scout report` gathers every figure (evaluations, the training history, the budget sweep, test
episodes) into one JSON file; this script only draws and formats them, with matplotlib, so the
plots come from a well-kept plotting library and the numbers from Scout. Usage:

    .venv/bin/python tools/report/scout_report.py REPORT_DATA.json OUT_DIR

It writes OUT_DIR/REPORT.md and OUT_DIR/*.png. Any error is one line on stderr and exit status 1.
"""
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")  # headless: no display is needed or used
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402

MODE_NAMES = {"full": "full images", "i": "mode (i)", "ii": "mode (ii)", "iii": "mode (iii)"}
MODE_COLOURS = {"full": "#7f7f7f", "i": "#1f77b4", "ii": "#2ca02c", "iii": "#d62728"}
COMPARE_COLOURS = ["#9467bd", "#ff7f0e", "#8c564b", "#e377c2"]  # compared models' curves
DPI = 110


class ReportError(Exception):
    pass


def need(d, key, where):
    if not isinstance(d, dict) or key not in d:
        raise ReportError(f"{where}: missing field '{key}'")
    return d[key]


def pct(x, digits=2):
    return "—" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{100 * x:.{digits}f} %"


def pct_ci(interval):
    if interval is None:
        return "—"
    return f"{100 * interval['mean']:.2f} ± {100 * interval['ci95']:.2f} %"


def save(fig, out_dir, name):
    path = os.path.join(out_dir, name)
    fig.savefig(path, dpi=DPI, bbox_inches="tight")
    plt.close(fig)
    return name


# ---- figures --------------------------------------------------------------------------------


def plot_history(history, out_dir, compared=()):
    """Validation accuracy against training epochs, per mode, with the baselines; each compared
    model's agent curve (label, history) beside it on the same epoch axis."""
    if not history:
        return None
    fig, ax = plt.subplots(figsize=(8, 4.5))
    x = np.arange(1, len(history) + 1)
    modes = [h["mode"] for h in history]
    start = 0
    for k in range(1, len(history) + 1):  # shade each mode's epochs
        if k == len(history) or modes[k] != modes[start]:
            ax.axvspan(start + 0.5, k + 0.5, color=MODE_COLOURS.get(modes[start], "#cccccc"), alpha=0.08, lw=0)
            ax.text((start + k + 1) / 2, 0.02, MODE_NAMES.get(modes[start], modes[start]), ha="center",
                    va="bottom", fontsize=8, transform=ax.get_xaxis_transform())
            start = k

    def series(key):
        return np.array([np.nan if h.get(key) is None else h[key] for h in history], dtype=float)

    ax.plot(x, series("validation_accuracy"), "o-", color="black", ms=3, label="the agent (this mode's policy)")
    # Before mode (ii) the goal planner is untrained: its "learned goals" pass says nothing.
    goals_only = series("validation_goals_only")
    goals_only[[m not in ("ii", "iii") for m in modes]] = np.nan
    ax.plot(x, goals_only, "s--", color="#2ca02c", ms=3, label="learned goals, i.i.d. actions")
    ax.plot(x, series("validation_iid"), "^--", color="#1f77b4", ms=3, label="i.i.d. goals and actions")
    ax.plot(x, series("validation_full_image"), ":", color="#7f7f7f", label="the classifier on full images")
    # A compared run's schedule need not be this one's (full-image epochs or none): its curve is
    # shifted so that its first mode (i) epoch sits on this model's, and the shading stays this
    # model's.
    def first_mode_i(rows):
        return next((k for k, h in enumerate(rows) if h.get("mode") == "i"), None)

    lengths, starts, compared_values = [len(history)], [1], []
    for k, (label, other) in enumerate(compared):
        if not other:
            continue
        y = np.array([np.nan if h.get("validation_accuracy") is None else h["validation_accuracy"] for h in other],
                     dtype=float)
        ours, theirs = first_mode_i(history), first_mode_i(other)
        shift = ours - theirs if ours is not None and theirs is not None else 0
        ax.plot(np.arange(1, len(other) + 1) + shift, y, "o-", color=COMPARE_COLOURS[k % len(COMPARE_COLOURS)], ms=3,
                label=f"{label}: the agent")
        lengths.append(len(other) + shift)
        starts.append(1 + shift)
        compared_values.append(y)
    ax.set_xlabel("epoch (all modes, in order)" + ("; compared runs aligned at their first mode (i) epoch"
                                                   if len(lengths) > 1 else ""))
    ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(integer=True))
    ax.set_ylabel("validation accuracy")
    finite = np.concatenate([series(k) for k in ("validation_accuracy", "validation_iid", "validation_goals_only")] +
                            compared_values)
    finite = finite[np.isfinite(finite)]
    low = max(0.0, min(finite.min() if finite.size else 0.0, 0.8) - 0.02)
    ax.set_ylim(low, 1.0)
    ax.set_xlim(min(starts) - 0.5, max(lengths) + 0.5)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2, fontsize=8, frameon=False)
    ax.set_title("Validation accuracy against epochs (one stochastic pass per epoch)")
    return save(fig, out_dir, "accuracy_vs_epochs.png")


def plot_confusion(evaluation, out_dir):
    confusion = np.array(need(evaluation, "confusion", "eval"), dtype=float)
    classes = confusion.shape[0]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.6), gridspec_kw={"width_ratios": [1.15, 1]})
    im = ax.imshow(confusion, cmap="Blues", vmin=0, vmax=1)
    for i in range(classes):
        for j in range(classes):
            v = confusion[i, j]
            if v >= 0.005 or i == j:
                ax.text(j, i, f"{100 * v:.0f}" if i != j else f"{100 * v:.1f}", ha="center", va="center",
                        fontsize=7, color="white" if v > 0.5 else "black")
    ax.set_xticks(range(classes))
    ax.set_yticks(range(classes))
    ax.set_xlabel("predicted")
    ax.set_ylabel("true label")
    ax.set_title("Confusion matrix (% of each true class)")
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    per_class = np.diag(confusion)
    bx.bar(range(classes), per_class, color="#4c72b0")
    for c, v in enumerate(per_class):
        bx.text(c, v + 0.002, f"{100 * v:.1f}", ha="center", va="bottom", fontsize=7)
    mean = need(evaluation, "accuracy", "eval")["mean"]
    bx.axhline(mean, color="black", ls="--", lw=1, label=f"overall {100 * mean:.2f} %")
    bx.set_ylim(max(0.0, per_class.min() - 0.05), 1.0)
    bx.set_xticks(range(classes))
    bx.set_xlabel("class")
    bx.set_ylabel("accuracy")
    bx.set_title("Per-class accuracy")
    bx.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    return save(fig, out_dir, "confusion.png")


def plot_episodes(episodes, out_dir):
    """A grid of test episodes in the paper's style: what the robot revealed with its path and
    goals, the goal planner's heat map, and the prediction bars."""
    if not episodes:
        return None
    rows = len(episodes)
    fig, axes = plt.subplots(rows, 3, figsize=(8.4, 2.45 * rows), gridspec_kw={"width_ratios": [1, 1, 1.25]})
    axes = np.atleast_2d(axes)
    for r, ep in enumerate(episodes):
        w, h = ep["width"], ep["height"]
        floor = np.array(ep["floor"], dtype=float).reshape(h, w) / 255.0
        seen = np.array(ep["seen"], dtype=bool).reshape(h, w)
        shown = np.where(seen, floor, np.nan)
        a, b, c = axes[r]
        cmap = plt.get_cmap("gray").copy()
        cmap.set_bad("#3b4a6b")  # unseen pixels
        a.imshow(shown, cmap=cmap, vmin=0, vmax=1, interpolation="nearest")
        path = np.array(ep["path"], dtype=float)
        a.plot(path[:, 0], path[:, 1], "-", color="#ff9f1c", lw=1.2)
        a.plot(path[0, 0], path[0, 1], "o", color="#ff9f1c", ms=4)
        m = ep["patch_px"]
        # A window at cell (x, y) covers columns x - m // 2 .. x - m // 2 + m - 1 (pixel centres at
        # integers in imshow's coordinates, so its edges are half a pixel further out).
        for k, g in enumerate(ep["goals"]):
            a.add_patch(plt.Rectangle((g[0] - m // 2 - 0.5, g[1] - m // 2 - 0.5), m, m, fill=False, ec="#2ecc71",
                                      lw=1))
            a.text(g[0], g[1], str(k + 1), color="#2ecc71", fontsize=7, ha="center", va="center")
        end = path[-1]
        a.add_patch(plt.Rectangle((end[0] - m // 2 - 0.5, end[1] - m // 2 - 0.5), m, m, fill=False, ec="#00b4ff",
                                  lw=1.2))
        a.set_xlim(-0.5, w - 0.5)
        a.set_ylim(h - 0.5, -0.5)
        a.set_xticks([])
        a.set_yticks([])
        verdict = "right" if ep["prediction"] == ep["label"] else "wrong"
        a.set_title(f"label {ep['label']}, revealed {100 * seen.mean():.0f} %", fontsize=8)
        goal_map = ep.get("goal_map")
        if goal_map:
            b.imshow(floor, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
            heat = np.array(goal_map, dtype=float).reshape(h, w)
            b.imshow(heat, cmap="inferno", alpha=0.65, interpolation="nearest")
            b.set_title(f"goal map π_g, episode {ep.get('goal_map_episode', 1)}", fontsize=8)
        else:
            b.imshow(floor, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
            b.set_title("the digit (i.i.d. goals)", fontsize=8)
        b.set_xticks([])
        b.set_yticks([])
        p = np.array(ep["probabilities"], dtype=float)
        colours = ["#bbbbbb"] * len(p)
        colours[ep["prediction"]] = "#2ca02c" if verdict == "right" else "#d62728"
        if verdict == "wrong":
            colours[ep["label"]] = "#1f77b4"
        c.bar(range(len(p)), p, color=colours)
        c.set_ylim(0, 1)
        c.set_xticks(range(len(p)))
        c.tick_params(labelsize=7)
        c.set_title(f"π_c: predicts {ep['prediction']} ({verdict})", fontsize=8)
    fig.suptitle("Test episodes: revealed floor, path (orange), goals (green), final window (blue);\n"
                 "goal heat map; prediction (green right, red wrong, blue the true class)", fontsize=8)
    # Keep the two-line title clear of the first row's titles (tight_layout ignores suptitle).
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.5 / fig.get_figheight()))
    return save(fig, out_dir, "episodes.png")


def plot_budget(sweep, paper, model_point, out_dir):
    points = need(sweep, "points", "sweep")
    if not points:
        return None
    fig, ax = plt.subplots(figsize=(7.5, 4.6))
    trained = sweep.get("trained", {"patch_px": 6, "episodes": 4, "steps": 5})
    for kind, marker, colour, label in (
            ("patch", "o-", "#1f77b4", f"patch size m (E × T = {trained['episodes']} × {trained['steps']})"),
            ("moves", "s-", "#d62728", f"episodes E × moves T (m = {trained['patch_px']})")):
        pts = sorted((p for p in points if p["kind"] == kind), key=lambda p: p["revealed_fraction"])
        if not pts:
            continue
        xs = [p["revealed_fraction"] for p in pts]
        ys = [p["accuracy"] for p in pts]
        ax.plot(xs, ys, marker, color=colour, ms=4, label=label)
        for p in pts:
            tag = f"m={p['patch_px']}" if kind == "patch" else f"{p['episodes']}×{p['steps']}"
            ax.annotate(tag, (p["revealed_fraction"], p["accuracy"]), textcoords="offset points", xytext=(4, -10),
                        fontsize=7, color=colour)
    if model_point is not None:
        ax.plot([model_point[0]], [model_point[1]], "*", color="black", ms=12, label="this model, as trained")
    paper_fraction = paper.get("revealed_fraction")
    if paper_fraction is not None:
        ax.plot([paper_fraction], [paper["accuracy"] / 100], "D", color="#9467bd", ms=7,
                label=f"the paper: {paper['accuracy']:.2f} % (m = 6, 4 × 5; at Scout's coverage of that task)")
    # Other models' curves (E × T at their m), e.g. the paper's agent beside the shipped one.
    for k, other in enumerate(sweep.get("compared", [])):
        pts = sorted(need(other, "points", "sweep.compared"), key=lambda p: p["revealed_fraction"])
        if not pts:
            continue
        colour = ("#2ca02c", "#ff7f0e", "#7f7f7f")[k % 3]
        ax.plot([p["revealed_fraction"] for p in pts], [p["accuracy"] for p in pts], "^--", color=colour, ms=4,
                label=f"{other['label']}: episodes E × moves T")
    # The glimpse models: another task (glimpses jump anywhere), at the most their glimpses reveal.
    for k, g in enumerate(paper.get("glimpse_models", [])):
        ax.plot([g["revealed_fraction"]], [g["accuracy"] / 100], "P", color="#8c564b", ms=9, alpha=1 - 0.25 * k,
                label=f"{g['source']}: {g['accuracy']:.2f} % with {g['glimpses']} glimpses of "
                      f"{g['side']}×{g['side']} (another task; at most this share)")
    ax.set_xlabel("fraction of the floor's pixels revealed by the end (mean over episodes)")
    ax.set_ylabel("test accuracy")
    ax.set_xlim(0, 1)
    ax.set_ylim(max(0.0, min(p["accuracy"] for p in points) - 0.05), 1.0)
    ax.grid(alpha=0.3)
    # Below the axes: its long labels span the plot's width, and inside it they hid the low points.
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), frameon=False)
    ax.set_title(f"Accuracy against the observation budget ({sweep['digits']} test digits, "
                 f"{sweep['runs']} run{'s' if sweep['runs'] != 1 else ''} each)", fontsize=9)
    return save(fig, out_dir, "budget.png")


# ---- REPORT.md ------------------------------------------------------------------------------


def baseline_runs_text(evaluation):
    """How many runs the baselines had, where the evaluation says (older reports ran them every run)."""
    runs = evaluation.get("baselines", {}).get("runs")
    return f" (the baselines {runs} each)" if runs else ""


def error_removal(evaluation):
    """The shares of the i.i.d. errors that learned goals and then learned actions remove."""
    base = evaluation.get("baselines", {})
    iid, goals = base.get("iid"), base.get("goals_only")
    acc = evaluation["accuracy"]["mean"]
    if iid is None or goals is None or iid >= 1:
        return None
    e0, e1, e2 = 1 - iid, 1 - goals, 1 - acc
    return (e0 - e1) / e0, (e1 - e2) / e0


def table_rows(data):
    paper = data["paper"]
    rows = []
    rows.append(("The paper (GPU, 60,000 digits)", f"{paper['accuracy']:.2f} ± {paper['ci95']:.2f} %",
                 f"{paper['top2']:.2f} %", f"{paper['full_image']:.2f} %", "—", "paper, § Experiments"))
    rows.append(("The paper, transfer (ResNet-18)", f"{paper['transfer']:.2f} % (max)", "—", "—", "—",
                 "paper, Fig. (transfer)"))
    for entry in [data["model"]] + data.get("compare", []):
        ev = entry["eval"]
        base = ev.get("baselines", {})
        rows.append((entry["label"], pct_ci(ev["accuracy"]), pct_ci(ev.get("top2")), pct(ev.get("full_image")),
                     f"{pct(base.get('iid'))} / {pct(base.get('goals_only'))}",
                     f"`{entry['eval_command']}`" if entry.get("eval_command") else entry.get("eval_source", "")))
    return rows


def write_report(data, figures, out_dir):
    model = data["model"]
    ev = model["eval"]
    lines = []
    add = lines.append
    add(f"# Scout report: {model['label']}")
    add("")
    add(f"Model `{model['path']}`; evaluated on {ev.get('images', '?')} digits "
        f"({ev.get('data', 'the official MNIST test set')}), {ev.get('runs', '?')} stochastic runs"
        f"{baseline_runs_text(ev)}, precision {ev.get('precision', '?')}. Generated by `{data['command']}` in {data['seconds']:.0f} s"
        f" on {data.get('cpu', 'this CPU')}.")
    add("")
    add("## The paper's table beside Scout's")
    add("")
    add("| | accuracy (95 % CI) | top-2 | classifier on full images | i.i.d. / learned goals only | from |")
    add("|---|---|---|---|---|---|")
    for r in table_rows(data):
        add("| " + " | ".join(r) + " |")
    add("")
    add(f"Scout's accuracies are on {ev.get('data', 'the test digits')}, means over runs with 95 % Student-t "
        "intervals (half-widths); rows added with --compare say which digits in their own evaluation. The "
        "paper's figures are its own (the official test set, 20 runs); \"full images\" is the trained agent's "
        "classifier given the whole digit (u_c = x).")
    add("")
    for entry in [model] + data.get("compare", []):
        cmds = entry.get("train_commands") or []
        if cmds:
            add(f"**{entry['label']}** was trained with:")
            add("")
            add("```sh")
            for c in cmds:
                add(c)
            add("```")
            add("")
    removal = error_removal(ev)
    add("## Accuracy against epochs")
    add("")
    if figures.get("history"):
        add(f"![validation accuracy against epochs]({figures['history']})")
        add("")
        add("Each epoch ends with one stochastic pass over the validation digits (never the test set) under "
            "the mode's own policy, under the two baselines with the same classifier, and with the "
            "classifier on full images.")
    else:
        add("The model carries no training history.")
    add("")
    if removal and not ev.get("learned", {}).get("actions", True):
        # An agent whose action layer was not learned (none, or never trained) draws its axes
        # i.i.d.: it is its own goals-only baseline, so all it removes is the goals'.
        base = ev["baselines"]
        e0 = 1 - base["iid"]
        add(f"On the test digits, i.i.d. goals and actions leave {pct(e0)} errors; learned goals remove "
            f"{100 * (e0 - (1 - ev['accuracy']['mean'])) / e0:.0f} % of them. This agent's axes are drawn i.i.d. "
            f"(no action layer was learned; the paper: about a third of the errors each for goals and actions). "
            f"Greedy decoding (argmax goals, one run): {pct(ev.get('greedy'))}.")
        add("")
    elif removal:
        g, a = removal
        base = ev["baselines"]
        add(f"On the test digits, i.i.d. goals and actions leave {pct(1 - base['iid'])} errors; learned goals "
            f"remove {100 * g:.0f} % of them and learned actions another {100 * a:.0f} % (the paper: about a "
            f"third each). Greedy decoding (argmax goals and actions, one run): {pct(ev.get('greedy'))}.")
        add("")
    add("## Confusion matrix and per-class accuracy")
    add("")
    add(f"![confusion matrix]({figures['confusion']})")
    add("")
    diag = np.diag(np.array(ev["confusion"], dtype=float))
    add("| class | " + " | ".join(str(c) for c in range(len(diag))) + " |")
    add("|---|" + "---|" * len(diag))
    add("| accuracy | " + " | ".join(f"{100 * v:.1f}" for v in diag) + " |")
    add("")
    if figures.get("episodes"):
        add("## Test episodes")
        add("")
        add(f"![test episodes]({figures['episodes']})")
        add("")
        eps = data.get("episodes", [])
        right = sum(1 for e in eps if e["prediction"] == e["label"])
        add(f"{right} right and {len(eps) - right} wrong, drawn from the first test digits in order "
            f"(seed {data.get('episode_seed', '?')}).")
        add("")
    if figures.get("budget"):
        sweep = data["sweep"]
        add("## Accuracy against the observation budget")
        add("")
        add(f"![accuracy against the budget]({figures['budget']})")
        add("")
        add(f"The same networks (fully convolutional) at other patch sizes m and other E × T, each on the "
            f"first {sweep['digits']} test digits, {sweep['runs']} stochastic run(s), seed {sweep['seed']}.")
        add("")
        add("| m | E × T | revealed | accuracy |")
        add("|---|---|---|---|")
        for p in sorted(sweep["points"], key=lambda p: (p["kind"], p["revealed_fraction"])):
            add(f"| {p['patch_px']} | {p['episodes']} × {p['steps']} | {100 * p['revealed_fraction']:.1f} % | "
                f"{100 * p['accuracy']:.2f} % |")
        add("")
        for other in sweep.get("compared", []):
            add(f"{other['label']} at the same budgets: " + ", ".join(
                f"{p['episodes']} × {p['steps']}: {100 * p['accuracy']:.2f} %"
                for p in sorted(other["points"], key=lambda p: p["episodes"])) + ".")
            add("")
        glimpses = data["paper"].get("glimpse_models", [])
        if glimpses:
            add("The glimpse models, drawn for scale, solve another task: each glimpse may jump anywhere on the "
                "digit, where Scout's robot drives between its views. Their published points: " + "; ".join(
                    f"{g['source']}, {g['glimpses']} glimpses of {g['side']} × {g['side']}: {g['accuracy']:.2f} % "
                    f"(at most {100 * g['revealed_fraction']:.0f} % of the pixels)" for g in glimpses) + ".")
            add("")
    robustness = data.get("robustness")
    if robustness:
        rows = need(robustness, "rows", "robustness")
        base = rows[0]["accuracy"] if rows else None
        add("## Robustness in the scenario worlds")
        add("")
        add(f"The model, unchanged, in worlds where the physics matters (docs/SCENARIOS.md), each on the first "
            f"{robustness['digits']} test digits, {robustness['runs']} stochastic run(s), seed {robustness['seed']}; "
            "the first row is its own world.")
        add("")
        stalled = all("stalled_moves" in r for r in rows)
        add("| world | accuracy | change | revealed |" + (" stalled moves |" if stalled else ""))
        add("|---|---|---|---|" + ("---|" if stalled else ""))
        for i, r in enumerate(rows):
            change = "" if i == 0 else f"{100 * (r['accuracy'] - base):+.2f} points"
            add(f"| {r['world']} | {100 * r['accuracy']:.2f} ± {100 * r['ci95']:.2f} % | {change} | "
                f"{100 * r['revealed_fraction']:.1f} % |" + (f" {r['stalled_moves']:.2f} |" if stalled else ""))
        add("")
        if stalled:
            add("Stalled moves: per rollout, the moves that did not arrive (blocked by an obstacle or a teammate, "
                "or out of ticks).")
            add("")
    agents = data.get("scenario_agents")
    if agents:
        add("## Agents trained for a scenario world")
        add("")
        rows = need(agents, "rows", "scenario_agents")
        # Reports made before the baselines were measured have none: their columns are left out.
        baselines = all("iid_accuracy" in r for r in rows)
        add(f"Each in the world it was trained for, beside this model there; the first {agents['digits']} test "
            f"digits, {agents['runs']} stochastic run(s), seed {agents['seed']}. Stalled moves: per rollout, the "
            "moves that did not arrive (blocked by an obstacle or a teammate, or out of ticks)."
            + (" Beside each agent, in its world and with its classifier: random moves (i.i.d. goals and axes) and "
               "goals only (its goals, i.i.d. axes; the agent itself when it has no action planner; '-' when it "
               "learned no goals); floor seen: the share of the floor the patches saw." if baselines else ""))
        add("")

        def interval(mean, ci95):
            return "-" if mean is None else f"{100 * mean:.2f} ± {100 * ci95:.2f} %"

        add("| world | agent | accuracy |" + (" random moves | goals only | floor seen |" if baselines else "")
            + " stalled moves | this model |" + (" its floor seen |" if baselines else "") + " its stalled moves |")
        add("|---|---|---|" + ("---|---|---|" if baselines else "") + "---|---|" + ("---|" if baselines else "")
            + "---|")
        for r in rows:
            extra = (f" {interval(r['iid_accuracy'], r['iid_ci95'])} | "
                     f"{interval(r['goals_only_accuracy'], r['goals_only_ci95'])}"
                     f" | {100 * r['revealed_fraction']:.1f} % |") if baselines else ""
            model_seen = f" {100 * r['model_revealed_fraction']:.1f} % |" if baselines else ""
            add(f"| {r['world']} | `{r['agent']}` | {interval(r['accuracy'], r['ci95'])} |{extra} "
                f"{r['stalled_moves']:.2f} | {interval(r['model_accuracy'], r['model_ci95'])} |{model_seen} "
                f"{r['model_stalled_moves']:.2f} |")
        add("")
    add("## Files")
    add("")
    add("- `report-data.json`: every number above, as `scout report` gathered it")
    for name in sorted(v for v in figures.values() if v):
        add(f"- `{name}`")
    add("")
    with open(os.path.join(out_dir, "REPORT.md"), "w", encoding="utf-8") as f:
        f.write("\n".join(lines))


def main(argv):
    if len(argv) != 3:
        raise ReportError("usage: scout_report.py REPORT_DATA.json OUT_DIR")
    data_file, out_dir = argv[1], argv[2]
    try:
        with open(data_file, encoding="utf-8") as f:
            data = json.load(f)
    except (OSError, ValueError) as e:
        raise ReportError(f"{data_file}: {e}")
    if not os.path.isdir(out_dir):
        raise ReportError(f"{out_dir}: no such folder")
    model = need(data, "model", data_file)
    evaluation = need(model, "eval", data_file + ": model")
    figures = {
        "history": plot_history(model.get("history", []), out_dir,
                                [(c["label"], c.get("history", [])) for c in data.get("compare", [])]),
        "confusion": plot_confusion(evaluation, out_dir),
        "episodes": plot_episodes(data.get("episodes", []), out_dir),
    }
    sweep = data.get("sweep")
    if sweep:
        point = model.get("revealed_fraction")
        figures["budget"] = plot_budget(sweep, data["paper"], (point, evaluation["accuracy"]["mean"])
                                        if point is not None else None, out_dir)
    write_report(data, figures, out_dir)


if __name__ == "__main__":
    try:
        main(sys.argv)
    except ReportError as e:
        print(f"scout_report.py: {e}", file=sys.stderr)
        sys.exit(1)
    except (KeyError, TypeError, ValueError, IndexError) as e:
        print(f"scout_report.py: {sys.argv[1] if len(sys.argv) > 1 else 'input'}: malformed report data "
              f"({type(e).__name__}: {e})", file=sys.stderr)
        sys.exit(1)
