"""Print pyproject.toml's dependencies pinned to the oldest versions it admits, as pip constraints.

``numpy>=1.24`` becomes ``numpy==1.24``; an exact pin stays; an extra's dependency that applies
only to other Pythons (an environment marker) keeps its marker. A package declared twice (by the
package and by an extra) is pinned once, at the higher bound: the oldest environment installs
both. Used by ``.ci/test-oldest``.
"""

import re
import sys
from pathlib import Path

try:
    import tomllib
except ImportError:  # Python 3.10: the instructor extra installs tomli
    import tomli as tomllib

project = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text(encoding="utf-8"))["project"]
requirements = project["dependencies"] + [r for extra in project["optional-dependencies"].values() for r in extra]
pins: dict[str, tuple[tuple[int, ...], str]] = {}  # name: (bound, pin), in the order first declared
for requirement in requirements:
    spec, _, marker = requirement.partition(";")
    found = re.fullmatch(r"\s*([A-Za-z0-9_.-]+)\s*(?:>=|==)\s*([0-9][0-9A-Za-z.]*)\s*(?:,.*)?", spec)
    if not found:
        sys.exit(f"oldest-pins: cannot read a lower bound from {requirement!r}; write it as 'name>=X' or 'name==X'")
    bound = tuple(int(part) for part in re.findall(r"\d+", found[2]))
    pin = f"{found[1]}=={found[2]}" + (f"; {marker.strip()}" if marker else "")
    if found[1] not in pins or bound > pins[found[1]][0]:  # an extra may raise the base's bound
        pins[found[1]] = (bound, pin)
for _, pin in pins.values():
    print(pin)
