"""The viz side of the CLI: `tfcontact replay TRAJECTORY [--html OUT] [--open] [--speed S]`
and `tfcontact check TRAJECTORY`."""

from __future__ import annotations

import argparse
import signal
import sys
import time
import webbrowser

from tfcontact.errors import TrajectoryFileError
from tfcontact.plan_format.trajectory import load_trajectory
from tfcontact.viz.meshcat_replay import replay


def cli_replay(args: argparse.Namespace) -> int:
    """Run `tfcontact replay` from parsed arguments.

    Args (attributes of `args`):
        trajectory: path of `NAME.npz` or `NAME.json`.
        html: write a standalone page there instead of starting a live viewer.
        open: open the page (or the live viewer) in the default browser.
        speed: playback rate [-] (1 = real time; optional, default 1).
        fps: key frames per second (optional, default 30).
        forces: draw contact force arrows (optional, default False).
        plain_html: write the page's scripts uncompressed (optional, default False).

    Without `--html` a live meshcat server is started on 127.0.0.1; the command then
    waits until Ctrl-C (or SIGTERM) and stops the server.

    Returns:
        The exit code (0).

    Raises:
        TrajectoryFileError: the file is missing, damaged or foreign.
        RobotLoadError / InvalidInput: the robot in the sidecar cannot be rebuilt.
    """
    traj = load_trajectory(args.trajectory)
    options = dict(speed=float(getattr(args, "speed", 1.0) or 1.0),
                   fps=float(getattr(args, "fps", 30.0) or 30.0),
                   forces=bool(getattr(args, "forces", False)),
                   compress=not bool(getattr(args, "plain_html", False)))
    if args.html:
        result = replay(traj, html=args.html, **options)
        print(f"wrote {result.html} ({result.html_bytes / 1e6:.2f} MB, {result.n_frames} "
              f"frames, {result.duration:.3f} s of physical time at speed {result.speed:g})")
        if args.open:
            webbrowser.open(result.html.resolve().as_uri())
        return 0
    result = replay(traj, live=True, **options)
    if args.open:
        webbrowser.open(result.url)

    def stop(signum, frame):  # SIGTERM too: stop the server (it runs in its own session)
        raise KeyboardInterrupt

    # The handler goes in before the line that tells the user (or a test) the viewer runs:
    # a SIGTERM sent on reading that line must not find Python's default handler.
    previous = signal.signal(signal.SIGTERM, stop)
    try:
        print("the replay plays in the browser tab ('Animations' panel: play, reset, time);"
              " press Ctrl-C to stop the viewer", flush=True)
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, previous)
        result.close()
    return 0


def cli_check(args: argparse.Namespace) -> int:
    """Run `tfcontact check TRAJECTORY`: is the file intact, and does the plan hold?

    Loading checks the file (checksums, format version, content: `load_trajectory`);
    `tfcontact.plan_format.adapters.check_plan` then checks the physics from the recorded data and
    prints one line per check: status and verification, clock, gaps, the rebuilt robot,
    forward-kinematics gaps and the impacts (frozen pieces, recorded impulses, touchdowns
    inside a sampling interval) with their momentum balance.

    Args (attributes of `args`):
        trajectory: path of `NAME.npz` or `NAME.json`.
        penetration, tol: optional tolerances [m] and [-] (`CheckTolerances.penetration`,
            `CheckTolerances.model`; defaults 1e-3 and 1e-6).

    Returns:
        0 if the file is intact and every check passes, 1 if a physics check fails, 2 if
        the file is missing, damaged or foreign (one line on stderr names the problem).
    """
    from tfcontact.plan_format.adapters import CheckTolerances, check_plan

    try:
        traj = load_trajectory(args.trajectory)
    except TrajectoryFileError as err:
        print(f"damaged: {err}", file=sys.stderr)
        return 2
    tolerances = CheckTolerances(
        penetration=float(getattr(args, "penetration", None) or 1e-3),
        model=float(getattr(args, "tol", None) or 1e-6))
    result = check_plan(traj, tolerances=tolerances)
    print(result)
    return 0 if result.passed else 1
