"""Print requirements.txt with its exact pins lifted to the newest versions the course admits.

Each ``name==version`` becomes ``name`` (pip then takes the newest release that the other
requirements and pyproject.toml's ranges allow, e.g. ``mujoco<5``), except where a newer major
release is known not to be a drop-in: :data:`CAPS` keeps those within the major version the
book is written for. The weekly workflow installs this instead of the pins to learn early what a
new release breaks.
"""

import re
import sys
from pathlib import Path

#: Packages whose next major release changes what the course relies on.
CAPS = {
    "jupyter-book": "<2",  # v2 replaces _config.yml/_toc.yml (the design card fixes v1)
}
#: Tools kept at their pin: a new ruff changes lint rules and formatting, not what the course runs.
KEEP = {"ruff"}

requirements = Path(__file__).resolve().parents[1] / "requirements.txt"
for line in requirements.read_text(encoding="utf-8").splitlines():
    pin = re.fullmatch(r"([A-Za-z0-9_.-]+)==\S+", line.strip())
    if pin is None:
        if line.strip() and not line.lstrip().startswith("#"):
            sys.exit(f"newest-requirements: expected 'name==version' or a comment, got {line!r}")
        print(line)
        continue
    name = pin[1].lower()
    print(line.strip() if name in KEEP else pin[1] + CAPS.get(name, ""))
