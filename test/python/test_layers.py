"""The sources keep their layers (scripts/check_layers.py): nothing includes a layer above its own."""
import os
import subprocess
import sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
CHECK = os.path.join(ROOT, "scripts", "check_layers.py")


def run(root):
    return subprocess.run([sys.executable, CHECK, root], capture_output=True, text=True)


def write(root, path, text):
    full = os.path.join(root, path)
    os.makedirs(os.path.dirname(full), exist_ok=True)
    with open(full, "w") as f:
        f.write(text)


def test_the_repository_keeps_its_layers():
    result = run(ROOT)
    assert result.returncode == 0, result.stdout


def test_an_include_of_a_higher_layer_a_sibling_or_a_private_header_is_reported(tmp_path):
    root = str(tmp_path)
    write(root, "include/backlash_servo/model/params.h", '#include "backlash_servo/simulation/simulator.h"\n')
    write(root, "include/backlash_servo/simulation/simulator.h", '#include "backlash_servo/model/params.h"\n')
    write(root, "src/core/frequency/response.cpp", '#include "backlash_servo/identification/fit.h"\n')
    write(root, "include/backlash_servo/identification/fit.h", "\n")
    write(root, "src/core/numerics/linear_mode.h", "\n")
    write(root, "src/python/module.cpp", '#include "numerics/linear_mode.h"\n#include <vector>\n')
    write(root, "include/backlash_servo/plant/plant.h", '#include "numerics/linear_mode.h"\n')
    write(root, "test/unit/test_linear_mode.cpp", '#include "numerics/linear_mode.h"\n')
    result = run(root)
    assert result.returncode == 1
    lines = result.stdout.splitlines()
    assert lines[-1] == "4 include(s) against the layers", result.stdout
    assert any("model/params.h" in l and "higher layer 'simulation'" in l for l in lines)
    assert any("response.cpp" in l and "sibling 'identification'" in l for l in lines)
    assert any("module.cpp" in l and "private header" in l for l in lines)
    assert any("plant/plant.h" in l and "public header includes the private" in l for l in lines)
