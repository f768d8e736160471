"""Write a generated Lavaland instance as a world file (YAML + PNGs) that ``--world`` loads.

    ird-export-world --condition side_effects --seed 3 [--size 15] [--horizon 30]
        [--obs-dim 50] [--out worlds/exported] [--name side_effects_3]

Invariant: loading the file gives the same maps, features, proxy, posterior (same sampler
seed) and plans (latent conditions store the Lavaland seed that regenerates the observation
model, classifier and observation draws; docs/spec.md section 5 and
:mod:`ird_core.worlds.world_file`). What is written is loaded once before the path is printed.
"""

from __future__ import annotations

import argparse

from ird_core.worlds import lavaland, world_file

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The flags: the instance (condition, seed, size, horizon, obs_dim) and where to write it."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--condition", required=True, choices=lavaland.ALL_CONDITIONS)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--size", type=int, default=lavaland.DEFAULT_SIZE)
    parser.add_argument("--horizon", type=int, default=lavaland.DEFAULT_HORIZON)
    parser.add_argument("--obs-dim", type=int, default=lavaland.DEFAULT_DIM)
    parser.add_argument("--out", default="worlds/exported", help="output directory")
    parser.add_argument("--name", default=None, help="file stem (default <condition>_<seed>)")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Export one instance and print the world file's path; exit status 0 (2 on a bad argument)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        inst = lavaland.make_instance(args.condition, args.seed, size=args.size, horizon=args.horizon,
                                      obs_dim=args.obs_dim)
        path = world_file.export_instance(inst, args.out, args.name or f"{args.condition}_{args.seed}")
    except ValueError as exc:  # the library names its arguments; the command line names its flags
        text = str(exc)
        for argument, flag in (("directory: ", "--out: "), ("name: ", "--name: ")):
            text = flag + text[len(argument):] if text.startswith(argument) else text
        parser.error(text)
    world_file.load_world(path)  # what was written must load
    print(path)
    return 0
