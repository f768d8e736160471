"""One Markdown table from the runs of scripts/calibration_sweep.sh (each a run_experiments --out).

    python scripts/calibration_table.py RUN_DIR [RUN_DIR ...] > calibration.md

Per run (its temperature and prior sigma from run.json), per condition: the literal's lava and
target rates, and per Z-approximation IRD's lava %, target % and gap closed %, each with its 95%
interval, and R-hat > 1.1 counts. Exit status 2 when a folder is not a finished run.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ird_core.experiments.report import read_results_csv


def _pct(x: float) -> str:
    return f"{100 * x:.0f}"


def table(runs: list[Path]) -> str:
    lines = ["| temperature | prior sigma | sample scale | condition | literal lava / target % | planner | lava % [95% CI] | "
             "target % [95% CI] | gap closed % [95% CI] | R-hat > 1.1 |", "|---|---|---|---|---|---|---|---|---|---|"]
    for run in runs:
        settings = json.loads((run / "run.json").read_text())["settings"]
        rows = [s for s in read_results_csv(run / "results.csv") if s.experiment == "main"]
        literal = {s.condition: s for s in rows if s.planner == "literal"}
        for s in rows:
            if not s.planner.startswith("ird"):
                continue
            lit = literal[s.condition]
            lines.append(
                f"| {settings['temperature']:g} | {'calibrated' if settings['prior_sigma'] is None else format(settings['prior_sigma'], 'g')} | {settings.get('sample_scale', 'none')} | "
                f"{s.condition} | "
                f"{_pct(lit.lava_fraction)} / {_pct(lit.target_fraction)} | {s.planner} | "
                f"{_pct(s.lava_fraction)} [{_pct(s.lava_ci_low)}, {_pct(s.lava_ci_high)}] | "
                f"{_pct(s.target_fraction)} [{_pct(s.target_ci_low)}, {_pct(s.target_ci_high)}] | "
                f"{_pct(s.gap_closed)} [{_pct(s.gap_ci_low)}, {_pct(s.gap_ci_high)}] | {s.nonconverged} |")
    return "\n".join(lines) + "\n"


def main(argv: "list[str] | None" = None) -> int:
    runs = [Path(a) for a in (sys.argv[1:] if argv is None else argv)]
    missing = [str(r) for r in runs if not (r / "run.json").is_file() or not (r / "results.csv").is_file()]
    if not runs or missing:
        print(f"calibration_table.py: not a finished run (run.json, results.csv): {', '.join(missing) or '(none given)'}",
              file=sys.stderr)
        return 2
    sys.stdout.write(table(runs))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
