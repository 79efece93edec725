#!/usr/bin/env python3
"""Checks the layering of the sources from their include lines (docs/architecture.md).

Every source file belongs to a layer by its folder; a file may include its own folder and the layers below it,
never a layer above it nor a sibling of the same rank. The public API is include/backlash_servo/; the headers
beside the core's sources (src/core/<concept>/) are private: the core and the core's own tests include them,
nothing else, and no public header does. Prints every violation and exits 1 if there is one.

usage: scripts/check_layers.py [ROOT]
"""
import os
import re
import sys

# Bottom to top; folders of the same rank are siblings and do not read each other.
RANKS = {
    "model": 0,
    "numerics": 1,
    "rigid": 2,
    "drive": 2,
    "compliant": 3,
    "plant": 4,
    "simulation": 5,
    "frequency": 6,
    "identification": 6,
    "robot": 6,
    "config": 7,
    "files": 8,
    "studies": 9,
    "tools": 10,
    "ros": 10,
    "python": 10,
    "examples": 10,
    "tests": 11,
}
CORE = {name for name, rank in RANKS.items() if rank <= 6}
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)


def layer_of(path):
    """(layer, private) of a file under the root, or None for files outside the layered tree."""
    parts = path.split("/")
    if parts[:2] == ["include", "backlash_servo"] and len(parts) > 3:
        return parts[2], False
    if parts[:2] == ["src", "core"] and len(parts) > 3:
        return parts[2], True
    if parts[0] == "src" and len(parts) > 2:
        return parts[1], False
    if parts[0] in ("test", "bench"):
        return "tests", False
    return None


def target_of(spelled, includer_dir):
    """(layer, private) an include line names, or None (system, ROS, generated or the includer's own files)."""
    parts = spelled.split("/")
    if parts[0] == "backlash_servo" and len(parts) == 3 and parts[1] in RANKS:
        return parts[1], False
    if len(parts) == 2 and parts[0] in CORE:
        return parts[0], True
    local = os.path.normpath(os.path.join(includer_dir, spelled))
    return layer_of(local) if os.path.exists(local) else None


def violations(root):
    found = []
    for top in ("include", "src", "test", "bench"):
        for folder, _, names in os.walk(os.path.join(root, top)):
            for name in sorted(names):
                if not name.endswith((".h", ".hpp", ".cpp")):
                    continue
                path = os.path.relpath(os.path.join(folder, name), root)
                source = layer_of(path)
                if source is None:
                    continue
                layer, _ = source
                if layer not in RANKS:
                    found.append(f"{path}: folder '{layer}' is not a layer (add it to RANKS in {__file__})")
                    continue
                text = open(os.path.join(root, path), encoding="utf-8").read()
                for spelled in INCLUDE.findall(text):
                    target = target_of(spelled, os.path.join(root, os.path.dirname(path)))
                    if target is None:
                        continue
                    found += check(path, layer, spelled, *target)
    return found


def check(path, layer, spelled, target, private):
    if target == layer and not (private and path.startswith("include/")):
        return []
    if private and layer not in CORE and layer != "tests":
        return [f"{path}: includes the core's private header {spelled} (use the public API in include/)"]
    if private and path.startswith("include/"):
        return [f"{path}: a public header includes the private {spelled}"]
    if RANKS[target] > RANKS[layer]:
        return [f"{path}: layer '{layer}' includes {spelled} of the higher layer '{target}'"]
    if RANKS[target] == RANKS[layer]:
        return [f"{path}: '{layer}' includes {spelled} of its sibling '{target}' (same rank: neither reads the other)"]
    return []


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    found = violations(root)
    for line in found:
        print(line)
    print(f"{len(found)} include(s) against the layers")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
