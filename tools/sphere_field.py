#!/usr/bin/python3
"""A field of N spheres on a plane: a square grid (side ceil(sqrt(N))) of
radius-0.4 spheres one unit apart, alternating white Lambert and gold GGX
(alpha 0.15), the camera looking along the field from above its near edge.

    tools/sphere_field.py N --env data/env/sunrise.exr --out scene.json

The scene the scaling sweep renders at 1 to 8192 spheres and the stress
scene data/scenes/stress/sphere-field.json (1024).
"""
import argparse
import json
import math
from pathlib import Path


def field_scene(n, env, nside=256, width=128, height=64):
    side = max(1, math.ceil(math.sqrt(n)))
    spheres = []
    for i in range(n):
        row, col = divmod(i, side)
        spheres.append({"center": [col - (side - 1) / 2, 0.4, 0.0 - row], "radius": 0.4,
                        "material": "white" if (row + col) % 2 == 0 else "gold"})
    return {
        "camera": {"position": [0, 3.0, 6.0], "look_at": [0, 0, -side / 2], "fov": 50},
        "image": {"width": width, "height": height},
        "environment": {"file": env, "nside": nside},
        "materials": {
            "white": {"type": "lambert", "albedo": 0.8},
            "gold": {"type": "ggx", "alpha": 0.15, "conductor": [1.0, 0.78, 0.34]},
            "ground": {"type": "lambert", "albedo": 0.5},
        },
        "spheres": spheres,
        "planes": [{"point": [0, 0, 0], "normal": [0, 1, 0], "material": "ground"}],
    }


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("n", type=int, help="number of spheres")
    p.add_argument("--env", required=True, help="environment map, as the scene file should name it")
    p.add_argument("--nside", type=int, default=256)
    p.add_argument("--width", type=int, default=128)
    p.add_argument("--height", type=int, default=64)
    p.add_argument("--out", required=True)
    args = p.parse_args()
    if args.n < 0:
        p.error("n must be >= 0")
    scene = field_scene(args.n, args.env, args.nside, args.width, args.height)
    Path(args.out).write_text(scene_text(scene))


def scene_text(scene):
    """The scene as JSON with one key, material or sphere per line."""
    lines = []
    for key, value in scene.items():
        if isinstance(value, dict) and key == "materials":
            inner = ",\n".join(f"    {json.dumps(k)}: {json.dumps(v)}" for k, v in value.items())
            lines.append(f'  "{key}": {{\n{inner}\n  }}')
        elif isinstance(value, list):
            inner = ",\n".join("    " + json.dumps(v) for v in value)
            lines.append(f'  "{key}": [\n{inner}\n  ]')
        else:
            lines.append(f"  {json.dumps(key)}: {json.dumps(value)}")
    return "{\n" + ",\n".join(lines) + "\n}\n"


if __name__ == "__main__":
    main()
