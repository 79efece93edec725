#!/usr/bin/python3
"""Rewrites what derives from the parameter table (src/core/model/param_table.cpp): cfg/BacklashServo.cfg and the
generated parameter tables of docs/parameters.md (between <!-- BEGIN GENERATED params: SECTIONS --> and <!-- END GENERATED params -->).
usage: generate_params.py PATH/TO/backlash_params   (scripts/generate_params.sh finds it in build/)
test/unit/model/test_param_table.cpp fails while a committed file differs from what this writes."""
import re
import subprocess
import sys
from pathlib import Path

root = Path(__file__).resolve().parent.parent
tool = sys.argv[1]


def run(*args):
    return subprocess.run([tool, *args], check=True, capture_output=True, text=True).stdout


(root / "cfg" / "BacklashServo.cfg").write_text(run("--format", "cfg"))
readme = root / "docs" / "parameters.md"
pattern = re.compile(r"(<!-- BEGIN GENERATED params: ([a-z,]+) -->\n)(.*?)(<!-- END GENERATED params -->)", re.S)
text = pattern.sub(lambda m: m.group(1) + run("--format", "markdown", "--sections", m.group(2)) + m.group(4),
                   readme.read_text())
readme.write_text(text)
print("generate_params: wrote cfg/BacklashServo.cfg and docs/parameters.md")
