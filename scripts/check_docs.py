#!/usr/bin/python3
"""Runs the commands of the user documentation (README.md, docs/*.md) so that it can never go stale.

* A fenced block marked ```sh is run, command by command (a trailing backslash continues a line), with bash in a
  scratch directory holding a copy of config/ and the quick start's joint.yaml; each must exit 0 within 300 s.
* In any other fenced block, a line starting with "$ " is a transcript: its command is run the same way and every
  output line shown under it (up to the next "$ " or the block's end) must appear in what it prints. A shown line
  with "…" in it elides figures that no run can promise (a chaotic point's): its pieces must appear in that order on
  one printed line.
* A block marked ```LANG file=NAME, or ```yaml whose first line is "# NAME.yaml …" (the quick start's joint), is
  written to NAME in the scratch directory first.
* Blocks marked ```console are illustrations (long-running ROS graphs, covered by the rostests) and are not run.
* Every relative link [text](path) must name a file of the repository.

usage: check_docs.py            (from anywhere; needs the built package: source build/devel/setup.bash)
Prints one line per command and ends with "check_docs: N commands, M failures"; exits 1 on any failure."""
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FENCE = re.compile(r"^(\s*)```(\w*)(?:\s+file=(\S+))?\s*$")


def documents():
    return [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))


def blocks(path):
    """(language, [lines], file name or None) of every fenced block, indentation removed."""
    out, lang, body, indent, name = [], None, [], "", None
    for line in path.read_text().splitlines():
        m = FENCE.match(line)
        if lang is None and m:
            lang, body, indent, name = m.group(2), [], m.group(1), m.group(3)
        elif lang is not None and m and m.group(1) == indent and not m.group(3):
            out.append((lang, body, name))
            lang = None
        elif lang is not None:
            body.append(line[len(indent):] if line.startswith(indent) else line.lstrip())
    return out


def commands(lines):
    """Commands of a sh block: comments and blank lines dropped, backslash continuations joined."""
    out, current = [], ""
    for line in lines:
        if not current and (not line.strip() or line.lstrip().startswith("#")):
            continue
        if line.rstrip().endswith("\\"):
            current += line.rstrip()[:-1] + " "
            continue
        out.append(current + line)
        current = ""
    return out


def printed(expected, output):
    """Whether a shown output line appears in the output ("…" elides: the pieces in order on one line)."""
    if "…" not in expected:
        return expected in output
    pieces = [p.strip() for p in expected.split("…")]
    for line in output.splitlines():
        at = 0
        for piece in pieces:
            at = line.find(piece, at)
            if at < 0:
                break
            at += len(piece)
        else:
            return True
    return False


def run(command, cwd):
    # The tools by name too (transcripts show `backlash_design …`), besides rosrun.
    env = dict(os.environ, PATH=str(ROOT / "build" / "devel" / "lib" / "backlash_servo") + ":/usr/bin:" +
               os.environ.get("PATH", ""))
    p = subprocess.run(["bash", "-c", "set -o pipefail; " + command], cwd=cwd, capture_output=True, text=True,
                       timeout=300, env=env)
    return p.returncode, p.stdout + p.stderr


def main():
    failures, count = [], 0
    for doc in documents():
        for link in re.findall(r"\]\(([^)#:\s]+)(?:#[^)]*)?\)", doc.read_text()):
            if not (doc.parent / link).exists():
                failures.append("%s: broken link %s" % (doc.relative_to(ROOT), link))
    with tempfile.TemporaryDirectory() as scratch:
        shutil.copytree(ROOT / "config", Path(scratch) / "config")
        for doc in documents():
            for lang, body, name in blocks(doc):
                if not name and lang == "yaml" and body and re.match(r"#\s*[\w.-]+\.yaml\b", body[0]):
                    name = re.match(r"#\s*([\w.-]+\.yaml)", body[0]).group(1)
                if name:
                    (Path(scratch) / name).write_text("\n".join(body) + "\n")
        for doc in documents():
            where = str(doc.relative_to(ROOT))
            for lang, body, _ in blocks(doc):
                if lang == "sh":
                    for command in commands(body):
                        count += 1
                        code, output = run(command, scratch)
                        print("%s: %s -> %d" % (where, command, code))
                        if code != 0:
                            failures.append("%s: `%s` exited %d:\n%s" % (where, command, code, output))
                elif lang != "console":
                    i = 0
                    while i < len(body):
                        if not body[i].startswith("$ "):
                            i += 1
                            continue
                        command, i = body[i][2:], i + 1
                        while command.rstrip().endswith("\\") and i < len(body):
                            command, i = command.rstrip()[:-1] + " " + body[i].strip(), i + 1
                        expected = []
                        while i < len(body) and not body[i].startswith("$ "):
                            expected.append(body[i].strip())
                            i += 1
                        count += 1
                        code, output = run(command, scratch)
                        print("%s: %s -> %d" % (where, command, code))
                        missing = [e for e in expected if e and not printed(e, output)]
                        if code != 0 or missing:
                            failures.append("%s: `%s` exited %d; lines not printed: %s\nprinted:\n%s"
                                            % (where, command, code, missing, output))
    for f in failures:
        print("FAIL " + f)
    print("check_docs: %d commands, %d failures" % (count, len(failures)))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
