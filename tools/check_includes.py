#!/usr/bin/env python3
"""The include graph of host/ as modules (foo.h, foo.cpp and a private
foo_impl.h are one module):
fails, naming a cycle, when a module reaches itself through its includes,
which is what an include from a lower layer to a higher one makes. With
--layers, prints each module's layer: 0 includes nothing of the project's,
every other is one above the highest module it includes.

    tools/check_includes.py [--layers] [host]
"""
import argparse
import re
import sys
from pathlib import Path

INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)


def module_of(path):
    name = path.with_suffix("").as_posix()
    return name[: -len("_impl")] if name.endswith("_impl") and path.suffix == ".h" else name


def modules(root):
    """module name -> set of module names its files include (within root)."""
    files = sorted(p for p in root.rglob("*") if p.suffix in (".h", ".cpp"))
    names = {module_of(p.relative_to(root)) for p in files}
    graph = {n: set() for n in names}
    for p in files:
        me = module_of(p.relative_to(root))
        for inc in INCLUDE.findall(p.read_text()):
            for base in (p.parent, root):
                target = (base / inc).resolve()
                if target.is_file() and target.is_relative_to(root.resolve()):
                    other = module_of(target.relative_to(root.resolve()))
                    if other != me:
                        graph[me].add(other)
                    break
    return graph


def find_cycle(graph):
    """One cycle as a list of modules, or None (iterative depth-first search)."""
    state = {}
    for start in sorted(graph):
        if start in state:
            continue
        stack = [(start, iter(sorted(graph[start])))]
        path = [start]
        state[start] = "open"
        while stack:
            node, it = stack[-1]
            nxt = next(it, None)
            if nxt is None:
                state[node] = "done"
                stack.pop()
                path.pop()
            elif state.get(nxt) == "open":
                return path[path.index(nxt):] + [nxt]
            elif nxt not in state:
                state[nxt] = "open"
                stack.append((nxt, iter(sorted(graph[nxt]))))
                path.append(nxt)
    return None


def layers(graph):
    memo = {}

    def layer(n):
        if n not in memo:
            memo[n] = 1 + max((layer(m) for m in graph[n]), default=-1)
        return memo[n]

    return {n: layer(n) for n in graph}


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("root", nargs="?", default=str(Path(__file__).resolve().parent.parent / "host"))
    p.add_argument("--layers", action="store_true", help="print each module's layer")
    args = p.parse_args()
    root = Path(args.root)
    graph = modules(root)
    if not graph:
        print(f"check_includes: no .h or .cpp files under {root}", file=sys.stderr)
        return 1
    cycle = find_cycle(graph)
    if cycle:
        print("check_includes: include cycle (an include from a lower layer to a higher one): "
              + " -> ".join(cycle), file=sys.stderr)
        return 1
    edges = sum(len(v) for v in graph.values())
    if args.layers:
        by_layer = {}
        for n, l in layers(graph).items():
            by_layer.setdefault(l, []).append(n)
        for l in sorted(by_layer):
            print(f"{l}: {' '.join(sorted(by_layer[l]))}")
    print(f"check_includes: {len(graph)} modules, {edges} include edges, no cycle")
    return 0


if __name__ == "__main__":
    sys.exit(main())
