"""The ``multilayer`` command: run, resume, plot, validate, plugins, check-plugin, compare, study, stability.

Exit codes: 0 ok, 1 a run that failed, 2 an invalid case or plugin set
(the problems on stderr, one per line, without a traceback).

    multilayer validate cases/pulse.toml --set time.dt=5e-5
    multilayer run cases/pulse.toml --out results/pulse
    multilayer plugins --plugin my_layer.py
    multilayer check-plugin my-layer --plugin my_layer.py
    multilayer compare cases/membrane-mode.toml --vary layers[0].tension=2e4,8e4 --out results/tension
    multilayer study cases/pulse-koiter.toml --vary time.dt=1e-4,5e-5,2.5e-5 --out results/dt-study
    multilayer stability cases/pulse-koiter.toml --couplers kinematic-splitting,monolithic --out results/stability
    multilayer sweep cases/pulse-koiter.toml --vary time.dt=1e-4,5e-5 --vary layers[0].young=5e5,1e6 --out results/sweep
"""

from __future__ import annotations

import argparse
import shlex
import sys
import traceback
from collections.abc import Sequence
from pathlib import Path

from multilayer.plugin.loading import load_registry
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry, RegistryError
from multilayer.version import __version__

OK, FAILED, INVALID = 0, 1, 2
INTERRUPTED = 130  #: 128 + SIGINT, as a shell reports an interrupted command


def run_options(p: argparse.ArgumentParser, checkpoints: bool = True) -> None:
    """The options of commands that run a case."""
    if checkpoints:
        p.add_argument("--checkpoint-every", type=int, default=0, metavar="N",
                       help="write the whole state every N steps (and when interrupted), for 'multilayer resume'")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary at the end")
    p.add_argument("--no-plots", action="store_true", help="do not draw the run's figures at the end")


def executor_options(p: argparse.ArgumentParser, jobs: int | None = 1, jobs_help: str = "") -> None:
    """``--jobs`` and ``--scheduler`` of the commands that run many cases (:mod:`multilayer.campaign.executor`)."""
    p.add_argument("--jobs", type=int, default=jobs, metavar="N",
                   help=jobs_help or "runs at once: 1 runs them here one after the other, more on a local Dask "
                                     "cluster of N worker processes (a process pool without Dask)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on an existing Dask cluster, e.g. tcp://host:8786 (needs the extra 'dask'; "
                        "case files and --out on a file system the workers share)")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="multilayer", description="Fluid–multi-layered-structure interaction from TOML case files."
    )
    parser.add_argument("--version", action="version", version=f"multilayer {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def common(p: argparse.ArgumentParser, case: bool = True) -> None:
        if case:
            p.add_argument("case", type=Path, help="the TOML case file")
            p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                           help="override a value of the case, e.g. time.dt=5e-5 or layers[0].young=1e6")
        p.add_argument("--plugin", dest="plugins", action="append", default=[], metavar="MODULE",
                       help="also load plugins from this module (dotted name or .py file)")

    run = commands.add_parser("run", help="run a case, writing results to a folder")
    common(run)
    run.add_argument("--out", type=Path, required=True, help="results folder (created)")
    run_options(run)
    resume = commands.add_parser("resume", help="continue an interrupted or finished run from its checkpoint")
    resume.add_argument("out", type=Path, metavar="DIR", help="the results folder of the run")
    resume.add_argument("--until", type=float, metavar="T", help="run to this time (s) instead of the case's end")
    run_options(resume, checkpoints=False)
    resume.add_argument("--checkpoint-every", type=int, default=None, metavar="N",
                        help="checkpoint every N steps (default: as the run did)")
    common(resume, case=False)
    plot = commands.add_parser("plot", help="draw the figures of a results folder")
    plot.add_argument("out", type=Path, metavar="DIR", help="the results folder of a run")
    common(plot, case=False)
    common(commands.add_parser("validate", help="check a case file and report every problem"))
    plugins = commands.add_parser("plugins", help="list the available models, or one model's parameters")
    plugins.add_argument("name", nargs="?", help="show the parameters of this model")
    common(plugins, case=False)
    check = commands.add_parser("check-plugin", help="run the conformance checks of a layer plugin (multilayer.testing)")
    check.add_argument("name", help="the layer's name, as a case file writes it")
    check.add_argument("--param", dest="params", action="append", default=[], metavar="KEY=VALUE",
                       help="a parameter to build the layer with, changing the plugin's example")
    common(check, case=False)

    # -- compare: multilayer.campaign.compare ------------------------------------------
    compare = commands.add_parser("compare", help="run variants of a scene side by side and report the differences")
    compare.add_argument("cases", nargs="+", type=Path, metavar="CASE",
                         help="case files (one per variant, or one with --vary)")
    compare.add_argument("--out", type=Path, required=True, help="report folder; each variant runs into OUT/<label>/")
    compare.add_argument("--vary", metavar="KEY=A,B[,C...]",
                         help="one variant per value, each read like a --set value (inline tables too)")
    compare.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                         help="override a value of every variant")
    executor_options(compare)
    common(compare, case=False)

    # -- study: multilayer.campaign.study ----------------------------------------------
    study = commands.add_parser("study", help="speed against error: couplers x time steps (x meshes) against a reference")
    common(study)
    study.add_argument("--out", type=Path, required=True, help="study folder; each run goes into OUT/<coupler>/<key=value>/")
    study.add_argument("--couplers", metavar="A,B,...",
                       help="coupler names or inline tables replacing [coupler] (default: the case's own)")
    study.add_argument("--vary", dest="varies", action="append", default=[], metavar="KEY=A,B[,C...]",
                       help="values of a key, e.g. time.dt=1e-4,5e-5 (repeatable: the grid is their product)")
    study.add_argument("--reference", type=Path, metavar="CASE",
                       help="run this case file as the reference (default: the finest run of the highest-order coupler)")
    study.add_argument("--reference-set", dest="reference_sets", action="append", default=[], metavar="KEY=VALUE",
                       help="override a value of the reference only (after --set); without --reference the "
                            "reference is CASE with these overrides, e.g. time.dt=1.5625e-6")
    study.add_argument("--probes", metavar="NAME,...",
                       help="the η probes the errors are measured at (default: every η probe)")
    study.add_argument("--reuse", action="store_true",
                       help="keep the runs already in OUT that ended ok with the same case; run only the others")
    executor_options(study)

    # -- stability: multilayer.campaign.stability ----------------------------------------
    stability = commands.add_parser("stability", help="stability map: couplers x wall-to-fluid mass ratio "
                                                      "rho1*h/(rho_f*R) (x time steps)")
    common(stability)
    stability.add_argument("--out", type=Path, required=True,
                           help="map folder; each run goes into OUT/<coupler>/ratio=<r>/<key=value>/")
    stability.add_argument("--couplers", metavar="A,B,...",
                           help="coupler names or inline tables replacing [coupler] (default: the case's own)")
    stability.add_argument("--ratios", metavar="R1,R2,...",
                           help="values of rho1*h/(rho_f*R), set through the thin layer's density "
                                "(default: 1,0.1,0.01,0.001)")
    stability.add_argument("--layer", type=int, default=0, metavar="L",
                           help="the thin layer whose density sets the ratio (default: 0)")
    stability.add_argument("--vary", dest="varies", action="append", default=[], metavar="KEY=A,B[,C...]",
                           help="values of a key, e.g. time.dt=1e-4,1e-5 (repeatable: one map per combination)")
    executor_options(stability)

    # -- sweep: multilayer.campaign.sweep ----------------------------------------------------
    sweep = commands.add_parser("sweep", help="run a grid over any case keys ([sweep] table and --vary) on Dask, "
                                              "each run in OUT/runs/<digest>/")
    common(sweep)
    sweep.add_argument("--out", type=Path, required=True,
                       help="sweep folder: runs/<digest>/, plan.json, sweep.csv, sweep.md, sweep_<key>.png")
    sweep.add_argument("--vary", dest="varies", action="append", default=[], metavar="KEY=A,B[,C...]",
                       help="values of a key, read like --set values (repeatable; replaces the key in [sweep] grid)")
    executor_options(sweep, jobs=None, jobs_help="local Dask workers (default: one per core); 1 runs here, "
                                                 "one run after the other")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``multilayer`` console script; returns the exit code."""
    args = _parser().parse_args(argv)
    try:
        registry = load_registry(args.plugins)
        if args.command == "plugins":
            return _plugins(registry, args.name)
        if args.command == "plot":
            return _plot(args.out)
        if args.command == "resume":
            return _run(None, args.out, registry, args)
        if args.command == "check-plugin":
            return _check_plugin(registry, args.name, args.params)
        if args.command == "compare":
            from multilayer.campaign import compare

            return compare.main(args.cases, args.out, args.vary, args.overrides, registry, args.jobs, args.plugins,
                                args.scheduler)
        if args.command == "study":
            from multilayer.campaign import study

            command = shlex.join(["multilayer", *(sys.argv[1:] if argv is None else argv)])
            return study.main(args.case, args.out, args.couplers, args.varies, args.reference, args.jobs,
                              args.overrides, registry, args.plugins, command, args.reference_sets,
                              args.probes.split(",") if args.probes else None, args.reuse, args.scheduler)
        if args.command == "stability":
            from multilayer.campaign import stability

            command = shlex.join(["multilayer", *(sys.argv[1:] if argv is None else argv)])
            return stability.main(args.case, args.out, args.couplers, args.ratios, args.varies, args.layer,
                                  args.jobs, args.overrides, registry, args.plugins, command, args.scheduler)
        if args.command == "sweep":
            from multilayer.campaign import sweep

            command = shlex.join(["multilayer", *(sys.argv[1:] if argv is None else argv)])
            return sweep.main(args.case, args.out, args.varies, args.jobs, args.overrides, registry, args.plugins,
                              args.scheduler, command)
        from multilayer.case.casefile import load_case

        case = load_case(args.case, args.overrides, registry)
    except CaseError as exc:
        print(f"{args.case}: invalid case", file=sys.stderr)
        print(str(exc), file=sys.stderr)
        return INVALID
    except RegistryError as exc:
        print(f"plugins: {exc}", file=sys.stderr)
        return INVALID
    if args.command == "validate":
        print(_describe(args.case, case))
        _describe_sweep(args.case)
        return OK
    if args.checkpoint_every < 0:
        print(f"--checkpoint-every = {args.checkpoint_every}: expected a whole number of steps >= 0", file=sys.stderr)
        return INVALID
    return _run(case, args.out, registry, args)


def _run(case: object | None, out: Path, registry: Registry, args: argparse.Namespace) -> int:
    """``run`` (a case) or ``resume`` (``case`` None: the folder's checkpoint)."""
    import time

    from multilayer.results.folder import ResultsError
    from multilayer.run.checkpoint import CheckpointError
    from multilayer.run.loop import resume_run, run_case
    from multilayer.run.progress import ProgressBar, summary

    if out.exists() and not out.is_dir():
        print(f"--out {out} is a file, not a folder", file=sys.stderr)
        return INVALID
    t0 = time.perf_counter()
    bar = None
    try:
        if case is not None:
            bar = ProgressBar(case.time.steps, case.time.end, enabled=None if not args.quiet else False)
            result = run_case(case, out, registry, checkpoint_every=args.checkpoint_every, progress=bar)
        else:
            from multilayer.run.checkpoint import load

            saved = load(out, registry, args.until)
            bar = ProgressBar(saved.case.time.steps, saved.case.time.end, saved.tally.steps,
                              enabled=None if not args.quiet else False)
            result = resume_run(out, args.until, registry, checkpoint_every=args.checkpoint_every, progress=bar)
    except (ResultsError, CheckpointError) as exc:
        print(f"{'run' if case is not None else 'resume'}: {exc}", file=sys.stderr)
        return INVALID
    except Exception:  # a bug, not a user mistake: the traceback helps
        traceback.print_exc()
        print(f"run failed; partial results in {out}", file=sys.stderr)
        return FAILED
    finally:
        if bar is not None:
            bar.close()
    if not args.no_plots and result.steps:
        _plot(out, quiet=True)
    if not args.quiet:
        print(summary(result, time.perf_counter() - t0, out, checkpoint=(out / "checkpoint.pkl").is_file()))
    if result.status == "interrupted":
        return INTERRUPTED
    if result.status != "ok":
        print(f"run failed: {result.reason}", file=sys.stderr)
        return FAILED
    return OK


def _plot(out: Path, quiet: bool = False) -> int:
    from multilayer.results.figures import plot_run

    if not (out / "summary.json").is_file():
        print(f"plot: {out} is not a results folder (no summary.json)", file=sys.stderr)
        return INVALID
    try:
        written = plot_run(out)
    except Exception as exc:  # a figure is a by-product: say so, keep the run's status
        print(f"plot: the figures of {out} could not be drawn ({type(exc).__name__}: {exc})", file=sys.stderr)
        return FAILED
    if not quiet:
        print("\n".join(str(p) for p in written) or f"plot: nothing to draw in {out}")
    return OK


def _describe(path: Path, case: object) -> str:
    layers = ", ".join(f"{layer.model} ({'thin' if layer.thin else 'thick'})" for layer in case.layers) or "none"
    fluid = case.fluid.model if case.fluid is not None else "none"
    g, t = case.geometry, case.time
    return "\n".join([
        f"{path}: valid" + (f" — {case.title}" if case.title else ""),
        f"  channel  L = {g.length:g} cm, R = {g.radius:g} cm; mesh {case.mesh.nz} x {case.mesh.nr}, order {case.mesh.order}",
        f"  time     {t.steps} steps of {t.dt:g} s to {t.end:g} s",
        f"  fluid    {fluid}",
        f"  layers   {layers}",
        f"  coupler  {case.coupler.model}",
        f"  digest   {case.digest[:16]}",
    ])


def _describe_sweep(path: Path) -> None:
    """For a case with a (valid) ``[sweep]`` table: how many runs it declares and that ``sweep`` runs them."""
    from multilayer.campaign.sweep import read_table

    table = read_table(path)
    if table is not None:
        print(f"  sweep    {table.size} runs over {', '.join(table.keys)}: 'multilayer sweep' runs them; "
              f"'run' runs the case as written, without [sweep]")


def _plugins(registry: Registry, name: str | None) -> int:
    entries = registry.all()
    if name is not None:
        chosen = [r for r in entries if r.name == name]
        if not chosen:
            from multilayer.plugin.registry import nearest

            hint = nearest(name, [r.name for r in entries])
            print(f"no plugin named {name!r}" + (f"; did you mean {hint!r}?" if hint else "") + registry.failure_note(),
                  file=sys.stderr)
            return INVALID
        for entry in chosen:
            print(f"{entry.kind} {entry.name} ({entry.package} {entry.version}): {entry.record.doc}")
            rows = [("name", "unit", "default", "accepts", "doc")]
            rows += [_param_row(p) for p in entry.record.params]
            print(_table(rows))
        return OK
    rows = [("kind", "name", "package", "version", "doc")]
    rows += [(r.kind, r.name, r.package, r.version, r.record.doc.strip().splitlines()[0] if r.record.doc.strip() else "")
             for r in entries]
    print(_table(rows))
    return OK


def _check_plugin(registry: Registry, name: str, settings: Sequence[str]) -> int:
    """``multilayer check-plugin NAME``: 0 when every check passes, 1 when one fails, 2 for an unknown name."""
    from multilayer.case.keys import parse_value
    from multilayer.plugin.registry import nearest
    from multilayer.testing import check_layer, example_params

    found = registry.find("layer", name)
    if found is None:
        other = next((r for r in registry.all() if r.name == name), None)
        if other is not None:
            print(f"{name!r} is a {other.kind} plugin; check-plugin checks layer plugins", file=sys.stderr)
            return INVALID
        hint = nearest(name, registry.names("layer"))
        print(f"no layer plugin named {name!r}" + (f"; did you mean {hint!r}?" if hint else "")
              + registry.failure_note(), file=sys.stderr)
        return INVALID
    params = example_params(found.record)  # --param changes the plugin's example
    for item in settings:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            print(f"--param {item!r}: expected KEY=VALUE, e.g. --param young=1e6", file=sys.stderr)
            return INVALID
        params[key.strip()] = parse_value(value)
    kind = "thin" if found.record.thin else "thick"
    print(f"check-plugin {name} ({found.package} {found.version}), a {kind} layer")
    results = check_layer(name, params, registry)
    for result in results:
        print(f"  {result}")
    failed = sum(not r.ok for r in results)
    print(f"{failed} of {len(results)} checks failed" if failed else f"all {len(results)} checks passed")
    return FAILED if failed else OK


def _param_row(param: object) -> tuple[str, ...]:
    from multilayer.plugin.problems import describe

    default = "required" if param.required else repr(param.default)
    return (param.name, param.unit, default, describe(param).split(" (")[0], param.doc)


def _table(rows: list[tuple[str, ...]]) -> str:
    widths = [max(len(str(row[i])) for row in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(str(c).ljust(w) for c, w in zip(row, widths)).rstrip() for row in rows)


if __name__ == "__main__":
    sys.exit(main())
