"""Following a command's arguments through the code: modules entered, re-entered, and calls back up.

Runs tiny ``analyze`` and ``design`` commands of a checkout (this one, or ``--root`` another, in a
child process on that checkout's ``src``) with a profile hook on every call of a function of the
package, and counts, as distinct call sites (so a loop over frames counts once):

* **modules entered**: the package's modules whose functions run;
* **re-entries**: a call into a module that is already on the call stack below another module
  (control went out of it and comes back in: ``a -> b -> a``), by (caller, callee) function;
* **calls back up the layers**: a call from a module of one stage into a module of a later stage
  (``docs/reference/architecture.md``: a stage imports only earlier ones), by (caller, callee).

Each is split by how the callee was reached: **by name** (a function the calling module defines or
imports: the code itself goes back) or **handed in** (a callback, a method of an object, a
subclass's override called by its base class: the caller was given the callee, as a journal is
given its row format or a table its columns).

    python benchmarks/argument_trace.py --out docs/figures/argument_trace_after.json
    python benchmarks/argument_trace.py --root /tmp/before --out docs/figures/argument_trace_before.json
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from checkout import checkout_arguments, commit_of, run_on, write_figures
from energy_margin._stages import STAGES

#: Run in the child: trace the commands and print the counts as JSON.
_CHILD = r"""
import contextlib, io, json, sys, tempfile
from pathlib import Path
from energy_margin.cli import main as cli_main
from energy_margin.cli.app import build_parser

STAGES = STAGES_HERE
MOVED = {"evaluation.designs": "design", "evaluation.design_space": "design", "evaluation.design_search": "design",
         "evaluation.design_optimizers": "design", "evaluation.design_display": "design",
         "control.verification": "design"}

def stage(module):
    parts = module.split(".")
    if len(parts) < 2 or parts[0] != "energy_margin":
        return None
    name = parts[1]
    return STAGES.index(name) if name in STAGES else -1

def by_name(frame):
    # Whether the caller reached this function by a name of its own module (defined or imported).
    caller = frame.f_back
    while caller is not None and not caller.f_globals.get("__name__", "").startswith("energy_margin"):
        caller = caller.f_back
    if caller is None:
        return False
    code = frame.f_code
    return any(getattr(value, "__code__", None) is code for value in caller.f_globals.values())

def trace(argv):
    stack, modules, reentries, upward = [], set(), {}, {}
    def profile(frame, event, arg):
        if event == "call":
            module = frame.f_globals.get("__name__", "")
            if not module.startswith("energy_margin"):
                stack.append(None)
                return
            modules.add(module)
            here = f"{module}:{frame.f_code.co_name}"
            caller = next((entry for entry in reversed(stack) if entry is not None), None)
            if caller is not None and caller[0] != module:
                below = [entry[0] for entry in stack if entry is not None]
                run_start = len(below)
                while run_start > 0 and below[run_start - 1] == caller[0]:
                    run_start -= 1
                named = by_name(frame)
                if module in below[:run_start]:
                    reentries[(caller[1], here)] = named
                s_caller, s_here = stage(caller[0]), stage(module)
                if s_caller is not None and s_here is not None and s_caller >= 0 and s_here > s_caller:
                    upward[(caller[1], here)] = named
            stack.append((module, here))
        elif event == "return":
            if stack:
                stack.pop()
    sys.setprofile(profile)
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            status = cli_main(argv)
    finally:
        sys.setprofile(None)
    if status != 0:
        raise SystemExit(f"energy-margin {' '.join(argv)} exited {status}")
    def sites(found, named):
        return sorted(f"{a} -> {b}" for (a, b), how in found.items() if how == named)
    return {
        "modules_entered": len(modules),
        "reentries": sum(reentries.values()),
        "calls_back_up": sum(upward.values()),
        "reentries_handed_in": len(reentries) - sum(reentries.values()),
        "calls_back_up_handed_in": len(upward) - sum(upward.values()),
        "reentry_sites": sites(reentries, True),
        "call_back_up_sites": sites(upward, True),
        "reentry_sites_handed_in": sites(reentries, False),
        "call_back_up_sites_handed_in": sites(upward, False),
    }

sub = next(a for a in build_parser()._actions if a.__class__.__name__ == "_SubParsersAction")
new = any("--expansions" in a.option_strings for a in sub.choices["analyze"]._actions)
expansions = "--expansions" if new else "--iterations"
TINY = ["--objects", "2", "--trajectories", "2", "--frames", "3", "--seed", "1"]
results = {}
with tempfile.TemporaryDirectory() as work:
    data = str(Path(work) / "data")
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert cli_main(["generate", "--task", "pushing", *TINY, "--out", data]) == 0
    results["analyze"] = trace(["analyze", data, expansions, "10", "--seed", "1", "--workers", "1"])
    results["design"] = trace([
        "design", "--task", "pushing", "--param", "pusher_width=0.4:1.0", "--optimizer", "grid",
        "--evaluations", "2", "--verify", "1", expansions, "10", *TINY, "--out", str(Path(work) / "design"),
    ])
print(json.dumps(results))
"""


def measure(root: Path) -> dict[str, Any]:
    """The counts of the checkout ``root``, measured in a child process on its sources."""
    return run_on(root, _CHILD.replace("STAGES_HERE", repr(STAGES)), required=True)


def main() -> None:
    args = checkout_arguments(__doc__)
    root = args.root
    commit = commit_of(root)
    results = {"commit": commit, **measure(root)}
    print(f"checkout {root} at {commit}")
    for command in ("analyze", "design"):
        entry = results[command]
        print(
            f"  {command:<8} {entry['modules_entered']:>4} modules entered; by name: {entry['reentries']:>3} "
            f"re-entries, {entry['calls_back_up']:>3} calls back up the layers; handed in: "
            f"{entry['reentries_handed_in']:>3} and {entry['calls_back_up_handed_in']:>3}"
        )
        for site in (*entry["reentry_sites"], *entry["call_back_up_sites"]):
            print(f"      {site}")
    write_figures(args.out, results)


if __name__ == "__main__":
    main()
