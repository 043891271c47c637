"""The ``rodnet`` command: ``run`` a scene file, ``demo`` the reference deployment, ``validate``
the validation cases, ``bench`` the work-precision study of the reference deployment, ``render``
the movie of a run, ``compile`` the kernels ahead of time."""

from __future__ import annotations

import argparse
import os
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from rodnet.data import reference_scene_text

if TYPE_CHECKING:
    from rodnet.report.build import ReportBuilder

EXIT_BAD_INPUT, EXIT_FAILED = 2, 1


SOURCE = Path(__file__).resolve().parents[1]
"""The source tree rodnet runs from (an editable install): its ``validation/cases`` and
``tests`` are what ``rodnet validate`` runs, from any working directory."""


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="rodnet", description=(
        "Tether-net simulation: Cosserat rod threads and a lumped-parameter reference."))
    from rodnet import __version__

    parser.add_argument("--version", action="version", version=f"rodnet {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scene file")
    run.add_argument("scene", type=Path, help="scene TOML file")
    demo = sub.add_parser("demo", help="run the built-in reference deployment with Cosserat "
                          "threads and the lumped reference side by side")
    demo.add_argument("--quick", action="store_true",
                      help="the lumped reference alone (a few seconds)")
    demo.add_argument("--no-movie", action="store_true",
                      help="do not draw deployment.mp4 (rodnet render draws it later)")
    val = sub.add_parser("validate", help="run the validation cases and write a report")
    val.add_argument("--cases", type=Path, default=SOURCE / "validation" / "cases",
                     help="folder of cases (default: the source tree's validation/cases)")
    val.add_argument("-o", "--output", type=Path, default=Path("validation/reports"),
                     help="folder of the table validation.md (default: validation/reports)")
    val.add_argument("--fast", action="store_true", help="skip the cases marked slow")
    val.add_argument("--no-tests", action="store_true",
                     help="do not run the slow validation tests (pytest -m slow tests)")
    val.add_argument("--report", type=Path, default=None, metavar="DIR",
                     help="also write the validation report: DIR/index.html (each case's figure "
                     "against its reference, checks, convergence orders, versions, machine) and "
                     "DIR/report.json; runs the quick cases only, unless --slow")
    val.add_argument("--slow", action="store_true",
                     help="with --report: also run the slow cases and the slow validation tests "
                     "(without --report they run anyway, unless --fast)")
    ben = sub.add_parser("bench", help="work-precision study of the reference deployment "
                         "(long: hours; --quick: a small net in a few minutes)")
    ben.add_argument("-o", "--output", type=Path, default=Path("bench"),
                     help="folder of the tables, plot and stored runs (default: bench); runs "
                     "already stored there are not run again")
    study = ben.add_mutually_exclusive_group()
    study.add_argument("--quick", action="store_true", help="a 5 x 5 net for 1 s")
    study.add_argument("--defaults", action="store_true",
                     help="every model at its default settings beside explicit runs on the "
                     "full reference deployment (about two hours)")
    ben.add_argument("--only", default=None, metavar="TEXT",
                     help="only the models whose name contains TEXT (plus the references)")
    ben.add_argument("--limit", type=float, default=3600.0, metavar="SECONDS",
                     help="interrupt a run after this many wall seconds (default 3600)")
    swp = sub.add_parser("sweep", help="run a scene over a grid or Latin hypercube of keys "
                         "on a dask cluster (docs/sweeps.md)")
    swp.add_argument("scene", type=Path, help="scene TOML file")
    swp.add_argument("-o", "--output", type=_directory, required=True,
                     help="the sweep's folder (sweep.csv, sweep.json, runs/NNNN/); run again "
                     "to resume")
    swp.add_argument("--vary", action="append", default=[], metavar="KEY=V1,V2,...|KEY=LOW:HIGH",
                     help="a key's values (a grid axis) or range (Latin hypercube; needs "
                     "--samples); repeatable")
    swp.add_argument("--samples", type=_positive_int, default=None, metavar="N",
                     help="Latin-hypercube samples of the ranges (times the grid)")
    swp.add_argument("--seed", type=int, default=0, help="seed of the Latin hypercube (default 0)")
    swp.add_argument("--workers", type=_positive_int, default=None, metavar="N",
                     help="single-threaded worker processes of the local cluster "
                     "(default: one per core)")
    swp.add_argument("--scheduler", default=None, metavar="ADDRESS",
                     help="an existing dask scheduler (tcp://host:8786) instead of a local cluster")
    swp.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                     help="override a scene key in every run, as rodnet run --set (repeatable)")
    swp.add_argument("--quiet", action="store_true", help="no progress bar or progress lines")
    ren = sub.add_parser("render", help="write the movie of a run's saved frames "
                         "(OUTDIR/deployment.mp4)")
    ren.add_argument("outdir", type=Path, metavar="OUTDIR", help="the output folder of a run")
    ren.add_argument("-o", "--output", type=Path, default=None, metavar="FILE",
                     help="the movie file, .mp4 or .gif (default: OUTDIR/deployment.mp4, with "
                     "--gif OUTDIR/deployment.gif)")
    ren.add_argument("--gif", action="store_true", help="write a GIF instead of an MP4")
    ren.add_argument("--fps", type=_positive_float, default=None, help="frames per second "
                     "(default: the movie's frames in about 10 s, between 5 and 30 per second)")
    ren.add_argument("--size", type=_size, default=None, metavar="WxH",
                     help="frame size in pixels, even numbers (default 800x600)")
    ren.add_argument("--every", type=_positive_int, default=1, metavar="N",
                     help="draw every N-th saved frame, and the last (default 1: all)")
    comp = sub.add_parser("compile", help="compile the kernels of the demo and of small rod "
                          "runs ahead of time, into numba's cache (the README's set-up runs it; "
                          "the first run after it starts at once)")
    comp.add_argument("--processes", type=_positive_int, default=None, metavar="N",
                      help="worker processes (default: two on a machine with two cores or more)")
    for p in (run, demo):
        p.add_argument("-o", "--output", type=_directory, default=None,
                       help="output directory (default: the scene's output.directory)")
        p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                       help="override a scene key, e.g. --set simulation.dt=5e-4 (repeatable)")
        p.add_argument("--quiet", action="store_true", help="no progress line")
        p.add_argument("--threads", type=_positive_int, default=None, metavar="N",
                       help="threads of the compiled loops (default: one for small problems, "
                       "every core, or NUMBA_NUM_THREADS, from 150 elements on; 1 on a shared machine)")
    return parser


def _directory(text: str) -> Path:
    """A directory path, not empty (an argparse type: Path("") would be the working directory)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("is empty: name a directory (\".\" for the working "
                                         "directory)")
    return Path(text)


def _positive_int(text: str) -> int:
    """An integer >= 1 (an argparse type)."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, not {text!r}")
    return value


def _positive_float(text: str) -> float:
    """A finite number > 0 (an argparse type)."""
    try:
        value = float(text)
    except ValueError:
        value = 0.0
    if not 0.0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a number > 0, not {text!r}")
    return value


def _size(text: str) -> tuple[int, int]:
    """``WxH`` in pixels (an argparse type; see :func:`rodnet.viz.movie.parse_size`)."""
    from rodnet.viz.movie import parse_size

    try:
        return parse_size(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


demo_scene_text = reference_scene_text


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (0 ok, 1 failed run, 2 bad input, 130 interrupted by
    Ctrl-C, 143 by SIGTERM). Where the reader of the output goes away (``rodnet run ... | head``)
    the rest of the output is dropped, without a traceback: a run's status stays its own (its
    results are written before the lines that report them), any other command's is 1."""
    try:
        return _command(argv)
    except BrokenPipeError:
        _drop_output()
        return EXIT_FAILED
    except KeyboardInterrupt:   # before a run's own handling starts (loading, compiling)
        print("rodnet: interrupted (Ctrl-C) before the run started; nothing was written",
              file=sys.stderr)
        return 128 + int(signal.SIGINT)


def _drop_output() -> None:
    """Send the rest of the output nowhere: its reader went away (Python flushes both at exit)."""
    sys.stdout = open(os.devnull, "w")   # noqa: SIM115
    sys.stderr = open(os.devnull, "w")   # noqa: SIM115


def _command(argv: list[str] | None) -> int:
    """:func:`main` without its handling of a closed output."""
    args = _parser().parse_args(argv)
    if args.command == "validate":
        return _validate_command(args)
    if args.command == "bench":
        from rodnet.tools.bench import bench

        print(bench(args.output, args.quick, args.only, args.limit, args.defaults))
        return 0
    if args.command == "sweep":
        return _sweep(args)
    if args.command == "render":
        return _render(args)
    if args.command == "compile":
        from rodnet.tools.precompile import precompile

        print("rodnet compile: compiling the kernels of the demo and of small rod runs",
              file=sys.stderr)
        seconds, ok = precompile(args.processes, say=lambda line: print(line, file=sys.stderr))
        if not ok:
            print(f"rodnet compile: a run above did not end ok ({seconds:.1f} s); its kernels "
                  "compile on their first call in a run", file=sys.stderr)
            return EXIT_FAILED
        print(f"rodnet compile: done in {seconds:.1f} s", file=sys.stderr)
        return 0
    from rodnet.errors import SceneError
    from rodnet.scene import load_scene

    try:
        if args.command == "demo":
            from rodnet.demo import demo_scenes

            runs = demo_scenes(args.overrides, args.quick)
        else:
            runs = [("", load_scene(args.scene, args.overrides), "")]
    except SceneError as exc:
        print(f"rodnet: bad input: {exc}. Nothing was run and no output was written.", file=sys.stderr)
        return EXIT_BAD_INPUT
    warm = None
    if len(runs) > 1:   # the demo's later kernels compile on a second core meanwhile
        from rodnet.tools.precompile import warm_up

        warm = warm_up(args.overrides, args.threads)
    try:
        return _run_all(runs, args)
    finally:
        if warm is not None and warm.is_alive():
            warm.terminate()


def _run_all(runs, args: argparse.Namespace) -> int:  # type: ignore[no-untyped-def]
    """Run the ``(label, scene, folder)`` of ``runs`` in turn (stopping at the first that does
    not end ok) and, for the demo's two, compare them; returns the exit status."""
    results = []
    for label, scene, folder in runs:
        if len(runs) > 1:
            print(f"rodnet demo: {label}", file=sys.stderr)
        out = args.output if args.output is not None or not folder else \
            Path(scene.output.directory)      # None: run() names the scene key in its errors
        status, result = _run_one(scene, out / folder if folder else out, args,
                                  movie=args.command == "demo" and not folder
                                  and not args.no_movie)
        if status != 0:
            return status
        results.append(result)
    if len(results) == 2:
        from rodnet.demo import metrics_table, write_comparison

        labels = (runs[0][0], runs[1][0])
        for w in write_comparison(results[0].directory, labels):
            print(f"rodnet: warning: {w}", file=sys.stderr)
        print(f"rodnet demo: {labels[0]} against the {labels[1]} "
              f"(comparison.png in {results[0].directory}/):")
        print(metrics_table(labels, (results[0].summary, results[1].summary)))
    return 0


def _run_one(scene, out: Path | None, args: argparse.Namespace, movie: bool):  # type: ignore[no-untyped-def]
    """Run ``scene`` into ``out``, draw its figures, print its report; returns the exit status
    (0 ok, 1 failed, 2 bad input, 128 + signal when stopped) and the result."""
    from rodnet.errors import SceneError
    from rodnet.run import run
    from rodnet.viz.figures import draw_run_figures

    try:
        result = run(scene, out, progress=False if args.quiet else None, threads=args.threads)
    except SceneError as exc:
        print(f"rodnet: bad input: {exc}. Nothing was run and no output was written.", file=sys.stderr)
        return EXIT_BAD_INPUT, None
    except (ArithmeticError, ValueError, MemoryError) as exc:   # numpy's LinAlgError too
        if os.environ.get("RODNET_TRACEBACK"):
            raise
        folder = Path(out if out is not None else scene.output.directory)
        kept = (f"the frames computed so far are in {folder}/, summary.json saying so"
                if (folder / "summary.json").exists() else "nothing was written")
        print(f"rodnet: the run stopped on an error the scene's checks did not catch: "
              f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}. Look for "
              f"extreme values in the scene (a stiffness, size or duration many orders off); "
              f"{kept} (set RODNET_TRACEBACK=1 for the traceback)", file=sys.stderr)
        return EXIT_FAILED, None
    warnings = list(result.summary.get("warnings", [])) + draw_run_figures(result, scene.output,
                                                                           movie=movie)
    if args.threads is not None and result.summary.get("threads", args.threads) < args.threads:
        warnings.append(f"--threads {args.threads}: ran on {result.summary['threads']}, the "
                        "threads numba may use here (NUMBA_NUM_THREADS, else the cores)")
    try:
        for w in warnings:
            print(f"rodnet: warning: {w}", file=sys.stderr)
        _report(result)
    except BrokenPipeError:   # the results are written: the run's status stands
        _drop_output()
    if result.status == "interrupted":
        return 128 + int(getattr(signal, str(result.summary.get("signal", "SIGINT")))), result
    return (0 if result.status == "ok" else EXIT_FAILED), result


def _validate_command(args: argparse.Namespace) -> int:
    """``rodnet validate``: the cases, the slow tests unless left out, the report if asked for.
    With ``--report`` the quick set is the default: the slow cases and tests need ``--slow``."""
    if args.fast and args.slow:
        print("rodnet: bad input: --fast and --slow contradict each other: --fast leaves the slow "
              "cases out, --slow runs them; give one of them", file=sys.stderr)
        return EXIT_BAD_INPUT
    quick = args.fast or (args.report is not None and not args.slow)
    status, verdict, report = _validate(args.cases, args.output, quick, args.report)
    tests = "not run"
    if status != EXIT_BAD_INPUT and not args.no_tests and not quick and \
            (SOURCE / "tests").is_dir():
        import subprocess

        print("rodnet: running the slow validation tests (pytest -m slow tests)", file=sys.stderr)
        tail = ""   # pytest's last line: how many passed, failed, were skipped
        with subprocess.Popen([sys.executable, "-m", "pytest", "-q", "-m", "slow", "tests"],
                              cwd=SOURCE, stdout=subprocess.PIPE, text=True) as done:
            assert done.stdout is not None
            for line in done.stdout:   # shown as it comes: the slow tests take minutes
                sys.stdout.write(line)
                tail = line.strip() or tail
        ok = done.returncode in (0, 5)
        counts = tail.strip("= ").split(" in ")[0] if " in " in tail else ""
        tests = ("passed" if ok else "FAILED") + (f" ({counts})" if counts else "")
        status = status or (0 if ok else EXIT_FAILED)
        verdict += f"; slow validation tests {tests}"
    if report is not None:
        verdict += f"; HTML report in {report.write(not quick, tests)}"
    if verdict:
        print(f"rodnet validate: {'PASSED' if status == 0 else 'FAILED'}: {verdict}")
    return status


def _validate(cases: Path, output: Path, quick: bool, report_dir: Path | None
              ) -> tuple[int, str, ReportBuilder | None]:
    """Run every case under ``cases`` (``quick``: not those marked slow); write
    ``output/validation.md``. Returns the exit status (0 when all checks pass), the verdict (how
    many checks passed, where the report is) and, with ``report_dir``, the report's builder with
    every case added, to be written once the slow tests have run."""
    import tempfile

    from rodnet.errors import SceneError
    from rodnet.validate import case_folders, read_expected, report, validate_case

    every = case_folders(cases)
    try:
        slow = {f for f in every if read_expected(f).get("slow", False)}
    except SceneError as exc:
        print(f"rodnet: bad input: {exc}. Nothing was run.", file=sys.stderr)
        return EXIT_BAD_INPUT, "", None
    folders = [f for f in every if not (quick and f in slow)]
    if not folders:
        print(f"rodnet: bad input: no validation cases (scene.toml + expected.toml) under {cases}",
              file=sys.stderr)
        return EXIT_BAD_INPUT, "", None
    builder = None
    if report_dir is not None:
        try:
            from rodnet.report.build import ReportBuilder

            builder = ReportBuilder(report_dir, every)
        except ImportError as exc:
            print(f"rodnet: --report needs matplotlib ({exc}): pip install -e '.[viz]'. Nothing "
                  "was run.", file=sys.stderr)
            return EXIT_BAD_INPUT, "", None
        except SceneError as exc:
            print(f"rodnet: bad input: {exc}. Nothing was run.", file=sys.stderr)
            return EXIT_BAD_INPUT, "", None
    results, failed_runs = [], []
    for folder in every:
        if folder not in folders:
            if builder is not None:
                builder.not_run(folder)
            continue
        print(f"rodnet: validating {folder.name} ...", file=sys.stderr)
        scratch = Path(tempfile.mkdtemp(prefix=f"rodnet-{folder.name}-"))
        outcome = validate_case(folder, scratch / "run" if builder else scratch)
        if builder is not None:
            builder.add(outcome, scratch)
        results += outcome.checks
        if outcome.failure:
            failed_runs.append(f"{folder.name}: {outcome.failure}")
    text = report(results)
    output.mkdir(parents=True, exist_ok=True)
    (output / "validation.md").write_text("# Validation report\n\n" + text + "\n")
    print(text)
    for line in failed_runs:
        print(f"rodnet: run failed: {line}", file=sys.stderr)
    passed = sum(r.passed for r in results)
    ok = passed == len(results) and not failed_runs
    verdict = (f"{passed} of {len(results)} checks passed in {len(folders)} cases"
               + (f", {len(failed_runs)} runs failed" if failed_runs else "")
               + (f", {len(every) - len(folders)} slow cases not run"
                  if len(every) > len(folders) else "")
               + f"; report in {output / 'validation.md'}")
    return (0 if ok else EXIT_FAILED), verdict, builder


def _render(args: argparse.Namespace) -> int:
    """``rodnet render``: check the folder and the options, then write the movie."""
    from rodnet.errors import SceneError
    from rodnet.viz.movie import DEFAULT_SIZE, movie_target, render_movie

    try:
        path, gif = movie_target(args.outdir, args.output, args.gif, args.fps)
    except SceneError as exc:
        print(f"rodnet render: bad input: {exc}. No movie was written.", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        render_movie(args.outdir, path, args.fps, args.size or DEFAULT_SIZE, gif, args.every)
    except Exception as exc:  # no OpenGL, no ffmpeg: say so without a traceback
        print(f"rodnet render: could not write {path}: {type(exc).__name__}: {exc}. Off-screen "
              "rendering needs libegl1 and libgl1-mesa-dri, the MP4 the ffmpeg of "
              "imageio-ffmpeg (pip install -e '.[viz]').", file=sys.stderr)
        return EXIT_FAILED
    print(f"rodnet render: wrote {path}")
    return 0


def _report(result) -> None:  # type: ignore[no-untyped-def]
    s = result.summary
    if result.status != "ok":
        what = "was stopped" if result.status == "interrupted" else "failed"
        reached = (f"load factor {s['simulated_time_s']:.4g}"
                   if s["scene"]["simulation"]["type"] == "static"
                   else f"t = {s['simulated_time_s']:.4g} s")
        print(f"rodnet: the run {what}: {result.message}. The {s['frames']} frames computed up to "
              f"{reached} are in {result.directory}/.", file=sys.stderr)
        return
    work = (f" ({s['newton_iterations']} Newton iterations, {s['rejected_steps']} rejected)"
            if s["newton_iterations"] else "")
    compiled = (f" ({s['compile_time_s']:.1f} s of it compiling kernels, a first run's cost)"
                if s.get("compile_time_s", 0.0) >= 0.5 else "")
    print(f"rodnet: done in {s['wall_time_s']:.2f} s wall{compiled}, {s['steps']} steps{work}; "
          f"results in {result.directory}/")
    for key, value in s["metrics"].items():
        print(f"  {key:28s} {value:.6g}")


def _sweep(args: argparse.Namespace) -> int:
    """``rodnet sweep``: plan and check every run, then run them on dask (rodnet.sweep)."""
    from rodnet import sweep
    from rodnet.errors import SceneError

    try:
        planned = sweep.plan(args.scene, args.vary, args.overrides, args.samples, args.seed)
        done = sweep.execute(planned, args.output, workers=args.workers, scheduler=args.scheduler,
                             progress=False if args.quiet else None)
    except SceneError as exc:
        print(f"rodnet: bad input: {exc}. Nothing was run and no output was written.", file=sys.stderr)
        return EXIT_BAD_INPUT
    counts = f"{done.ok} ok, {done.failed} failed" + (f", {done.pending} not run" if done.pending else "")
    if done.signal is not None:
        print(f"rodnet: the sweep was stopped by {done.signal} ({counts}); every finished run is "
              f"in {done.table}; run the same command again to resume.", file=sys.stderr)
        return 128 + int(getattr(signal, done.signal))
    print(f"rodnet: sweep done: {done.total} runs ({counts}; {done.skipped} were complete "
          f"already) in {done.wall_s:.1f} s wall; table in {done.table}")
    return EXIT_FAILED if done.failed else 0
