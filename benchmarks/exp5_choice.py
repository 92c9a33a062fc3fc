"""How Exp 5's robots choose in the tool-far test, by HP1's skills and HP2's training trials.

    python benchmarks/exp5_choice.py RUN [RUN ...]

RUN: directories of `python evaluate.py experiment=exp5` runs (their individuals.csv). For each
hypothesis, strategy and level (HP1: IM detectors = skills; HP2: training trials), over the
tool-far robots:
- `robots`, `success`;
- `pull alone`: robots whose learnt pull alone retrieves from posture 4; of those, the share whose
  first test action is that pull (`pull first`) and their success;
- `two moves only`: robots with a two-move route and no one-move route, and their success;
- `no route`: robots the world offers neither, and their success.
The routes are the world's (`routes_1`, `routes_2`), not what the robot knows.

A second table, over HP1's tool-behind robots that failed: how many have no one-move route, and of
the others how many began with touch and how many tried the pull at all.
"""
from pathlib import Path

import pandas as pd

from neuroimagery.core.arguments import ToolParser, path, run_tool
from neuroimagery.core.errors import UserInputError


def read(runs):
    return pd.concat([pd.read_csv(Path(r) / "individuals.csv") for r in runs], ignore_index=True)


def table(d):
    far = d[d.situation == "far"].copy()
    far["first"] = far.test_actions.fillna("").str.split(">").str[0]
    rows = []
    for (hyp, strategy, level), x in far.groupby(["hypothesis", "strategy", "level"]):
        pull = x[x.pull_alone > 0]
        two = x[(x.routes_1 == 0) & (x.routes_2 > 0)]
        none = x[(x.routes_1 == 0) & (x.routes_2 == 0)]
        rows.append({
            "hypothesis": hyp, "strategy": strategy, "level": level, "robots": len(x),
            "success": x.success.mean(),
            "pull alone": len(pull), "pull first": (pull["first"] == "retrieve").mean(),
            "their success": pull.success.mean(),
            "two moves only": len(two), "success (two)": two.success.mean(),
            "no route": len(none), "success (none)": none.success.mean(),
        })
    return pd.DataFrame(rows)


def behind_failures(d):
    b = d[(d.hypothesis == "hp1") & (d.situation == "behind") & (d.success == 0)].copy()
    acts = b.test_actions.fillna("")
    b["first"], b["tried_pull"] = acts.str.split(">").str[0], acts.str.split(">").apply(lambda a: "retrieve" in a)
    rows = []
    for (strategy, level), x in b.groupby(["strategy", "n_detectors"]):
        r = x[x.routes_1 > 0]
        rows.append({"strategy": strategy, "detectors": level, "failed": len(x), "no one-move route": len(x) - len(r),
                     "route, touch first": int((r["first"] == "touch").sum()), "route, pull tried": int(r.tried_pull.sum())})
    return pd.DataFrame(rows)


def main(argv=None):
    p = ToolParser(description=__doc__.splitlines()[0])
    p.add_argument("runs", nargs="+", type=path)
    a = p.parse_args(argv)
    for r in a.runs:
        if not (Path(r) / "individuals.csv").is_file():
            raise UserInputError(f"{r} has no individuals.csv (not an Exp 5 run directory)")
    pd.set_option("display.width", 200)
    d = read(a.runs)
    print(table(d).round(2).to_string(index=False))
    print("\nHP1, tool behind, the robots that failed")
    print(behind_failures(d).to_string(index=False))


if __name__ == "__main__":
    raise SystemExit(run_tool(main))
