"""``sidprep linearize SCENE``: eigenfrequencies and mode shapes of the mechanism at its assembled
start (sidprep.solver.scene_modes.linearize_scene), as a table or JSON."""

from __future__ import annotations

from sidprep.cli.options import add_count, add_json, add_quiet, process_setup

#: entries of a mode shape printed in the table (the largest, by magnitude)
SHAPE_ENTRIES = 3


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "linearize", help="eigenfrequencies and mode shapes of a scene's mechanism at its assembled start",
        description="Assemble the scene's start (joints closed, as sidprep simulate does) and linearise the "
                    "constrained equations there: M and the tangent stiffness K (elastic, joint springs, "
                    "gravity and the other effects the scene includes) on the joints' null space. Prints the "
                    "eigenfrequencies (0 Hz: rigid-body motions and unstable directions) and the largest "
                    "entries of each mode shape (body, coordinate). --json: frequencies_hz, n_rigid, coordinates, shapes (columns).")
    p.add_argument("scene", metavar="SCENE", help="scene file (.toml)")
    add_count(p)
    add_json(p)
    add_quiet(p)
    p.set_defaults(func=run, process_setup=process_setup)


def shape_summary(shape, coordinates, entries: int = SHAPE_ENTRIES) -> str:
    """The largest entries of one mass-normalised shape, e.g. 'rod q.3 +0.98, crank omega.z -0.12'."""
    import numpy as np

    order = np.argsort(-np.abs(shape))[:entries]
    return ", ".join(f"{coordinates[k][0]} {coordinates[k][1]} {shape[k]:+.3g}" for k in order if shape[k] != 0)


def run(args) -> int:
    import json

    from sidprep.errors import InputError
    from sidprep.solver.scene_modes import linearize_scene

    if args.count < 1:
        raise InputError(f"--count {args.count}: must be >= 1")
    linearized = linearize_scene(args.scene)
    scene, modes = linearized.scene, linearized.modes
    n = min(modes.n_rigid + args.count, len(modes.frequencies_hz))
    if args.json:
        print(json.dumps({"scene": str(args.scene), "n_rigid": modes.n_rigid,
                          "frequencies_hz": modes.frequencies_hz[:n].tolist(),
                          "coordinates": [list(c) for c in modes.coordinates],
                          "shapes": modes.shapes[:, :n].T.tolist()}))
        return 0
    if not args.quiet:
        print(f"{scene.title}: {len(modes.frequencies_hz)} modes at the assembled start, {modes.n_rigid} rigid-body "
              f"(0 Hz); the rigid-body modes and the first {n - modes.n_rigid} others")
    print(f"  {'mode':>4s}  {'f [Hz]':>12s}  largest entries of the shape (body coordinate value)")
    for k in range(n):
        print(f"  {k + 1:4d}  {modes.frequencies_hz[k]:12.4f}  {shape_summary(modes.shapes[:, k], modes.coordinates)}")
    unbalanced = int((modes.frequencies_hz == 0).sum()) - modes.n_rigid
    if unbalanced > 0 and not args.quiet:
        print(f"  note: {unbalanced} mode(s) at 0 Hz are not rigid-body motions: negative stiffness there (the start "
              "is not an equilibrium, e.g. a pendulum released sideways under gravity, or it is unstable)")
    return 0
