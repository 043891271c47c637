"""The ``rodnet`` command: ``run`` a scene file, ``demo`` the reference deployment, ``validate``
the validation cases, ``bench`` the work-precision study of the reference deployment, ``render``
the movie of a run."""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

from rodnet.data import reference_scene_text

EXIT_BAD_INPUT, EXIT_FAILED = 2, 1


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="rodnet", description=(
        "Tether-net simulation: Cosserat rod threads and a lumped-parameter reference."))
    from rodnet import __version__

    parser.add_argument("--version", action="version", version=f"rodnet {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scene file")
    run.add_argument("scene", type=Path, help="scene TOML file")
    demo = sub.add_parser("demo", help="run the built-in reference deployment")
    val = sub.add_parser("validate", help="run the validation cases and write a report")
    val.add_argument("--cases", type=Path, default=Path("validation/cases"),
                     help="folder of cases (default: validation/cases)")
    val.add_argument("-o", "--output", type=Path, default=Path("validation/reports"),
                     help="report folder (default: validation/reports)")
    val.add_argument("--fast", action="store_true", help="skip the cases marked slow")
    val.add_argument("--no-tests", action="store_true",
                     help="do not run the slow validation tests (pytest -m slow tests)")
    ben = sub.add_parser("bench", help="work-precision study of the reference deployment "
                         "(long: hours; --quick: a small net in a few minutes)")
    ben.add_argument("-o", "--output", type=Path, default=Path("bench"),
                     help="folder of the tables, plot and stored runs (default: bench); runs "
                     "already stored there are not run again")
    ben.add_argument("--quick", action="store_true", help="a 5 x 5 net for 1 s")
    ben.add_argument("--only", default=None, metavar="TEXT",
                     help="only the models whose name contains TEXT (plus the references)")
    ben.add_argument("--limit", type=float, default=3600.0, metavar="SECONDS",
                     help="interrupt a run after this many wall seconds (default 3600)")
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
    for p in (run, demo):
        p.add_argument("-o", "--output", type=Path, default=None,
                       help="output directory (default: the scene's output.directory)")
        p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                       help="override a scene key, e.g. --set simulation.dt=5e-4 (repeatable)")
        p.add_argument("--quiet", action="store_true", help="no progress line")
        p.add_argument("--threads", type=_positive_int, default=None, metavar="N",
                       help="threads of the compiled loops (default: one for small problems, "
                       "every core, or NUMBA_NUM_THREADS, from 150 elements on; 1 on a shared machine)")
    return parser


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
    Ctrl-C, 143 by SIGTERM)."""
    args = _parser().parse_args(argv)
    if args.command == "validate":
        status, verdict = _validate(args.cases, args.output, args.fast)
        if status != EXIT_BAD_INPUT and not args.no_tests and not args.fast \
                and Path("tests").is_dir():
            import subprocess

            print("rodnet: running the slow validation tests (pytest -m slow tests)",
                  file=sys.stderr)
            done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-m", "slow", "tests"])
            tests_ok = done.returncode in (0, 5)
            status = status or (0 if tests_ok else EXIT_FAILED)
            verdict += "; slow validation tests " + ("passed" if tests_ok else "FAILED")
        if verdict:
            print(f"rodnet validate: {'PASSED' if status == 0 else 'FAILED'}: {verdict}")
        return status
    if args.command == "bench":
        from rodnet.tools.bench import bench

        print(bench(args.output, args.quick, args.only, args.limit))
        return 0
    if args.command == "render":
        return _render(args)
    from rodnet.errors import SceneError
    from rodnet.scene import load_scene, scene_from_toml

    try:
        if args.command == "demo":
            scene = scene_from_toml(demo_scene_text(), args.overrides, source="rodnet demo")
        else:
            scene = load_scene(args.scene, args.overrides)
        from rodnet.run import run

        result = run(scene, args.output, progress=False if args.quiet else None,
                     threads=args.threads)
    except SceneError as exc:
        print(f"rodnet: bad input: {exc}. Nothing was run and no output was written.", file=sys.stderr)
        return EXIT_BAD_INPUT
    warnings = list(result.summary.get("warnings", []))
    movie = args.command == "demo"
    if result.status == "ok" and (scene.output.picture or scene.output.plot or movie) \
            and "mouth_area" in result.arrays:
        from rodnet.viz.figures import render_in_subprocess

        warnings += render_in_subprocess(result.directory, scene.output.picture, scene.output.plot,
                                         movie)
    for w in warnings:
        print(f"rodnet: warning: {w}", file=sys.stderr)
    _report(result)
    if result.status != "ok":
        if result.status == "interrupted":
            return 128 + int(getattr(signal, str(result.summary.get("signal", "SIGINT"))))
        return EXIT_FAILED
    return 0


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


def _validate(cases: Path, output: Path, fast: bool) -> tuple[int, str]:
    """Run every case under ``cases``; write ``output/validation.md``. Returns the exit status
    (0 when all checks pass) and the verdict: how many checks passed, where the report is."""
    import tempfile

    from rodnet.validate import case_folders, read_expected, report, run_case

    folders = [f for f in case_folders(cases) if not (fast and read_expected(f).get("slow", False))]
    if not folders:
        print(f"rodnet: bad input: no validation cases (scene.toml + expected.toml) under {cases}",
              file=sys.stderr)
        return EXIT_BAD_INPUT, ""
    results, failed_runs = [], []
    for folder in folders:
        print(f"rodnet: validating {folder.name} ...", file=sys.stderr)
        result, checks = run_case(folder, Path(tempfile.mkdtemp(prefix=f"rodnet-{folder.name}-")))
        results += checks
        if result.status != "ok":
            failed_runs.append(f"{folder.name}: {result.message}")
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
               + f"; report in {output / 'validation.md'}")
    return (0 if ok else EXIT_FAILED), verdict


def _report(result) -> None:  # type: ignore[no-untyped-def]
    s = result.summary
    if result.status != "ok":
        what = "was stopped" if result.status == "interrupted" else "failed"
        print(f"rodnet: the run {what}: {result.message}. The {s['frames']} frames computed up to "
              f"t = {s['simulated_time_s']:.4g} s are in {result.directory}/.", file=sys.stderr)
        return
    work = (f" ({s['newton_iterations']} Newton iterations, {s['rejected_steps']} rejected)"
            if s["newton_iterations"] else "")
    print(f"rodnet: done in {s['wall_time_s']:.2f} s wall, {s['steps']} steps{work}; results in "
          f"{result.directory}/")
    for key, value in s["metrics"].items():
        print(f"  {key:28s} {value:.6g}")
