"""PlatformIO pre-build script: generates the MAVLink C headers (tools/gen_mavlink.py) into
.pio/generated before compiling, with the interpreter PlatformIO runs under (.venv, which has
pymavlink)."""

import os
import subprocess
import sys

Import("env")  # noqa: F821 (provided by PlatformIO/SCons)

project_dir = env["PROJECT_DIR"]  # noqa: F821
subprocess.run(
    [
        sys.executable,
        os.path.join(project_dir, "tools", "gen_mavlink.py"),
        os.path.join(project_dir, ".pio", "generated"),
    ],
    check=True,
)
# On CPPPATH (not a raw -isystem flag) so SCons tracks the generated headers as dependencies.
env.Append(CPPPATH=[os.path.join(project_dir, ".pio", "generated")])  # noqa: F821
