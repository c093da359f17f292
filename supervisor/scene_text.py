"""Scene files as text, for the commands that write a variant of a user's scene (`./sabo replay --set`,
`./sabo study`): keys set to other values, relative mesh paths made absolute for a copy that lives elsewhere.
The variant is then checked by sabo_scene like any scene, so that an override that does not fit is refused
with the variant's file, line and key."""
from __future__ import annotations

import os
import re

from .errors import SaboError, EXIT_BAD_INPUT


def absolute_file_keys(text: str, scene_folder: str) -> str:
    """The scene's relative file paths (`file`, and every `..._file` key: `profile_file`, `raster_file`,
    `hydrograph_file`) made absolute against the scene's folder (a replayed scene or a study's variant lives
    elsewhere)."""
    def absolute(match: re.Match) -> str:
        path = match.group(2)
        if os.path.isabs(path):
            return match.group(0)
        return f'{match.group(1)}"{os.path.normpath(os.path.join(scene_folder, path))}"'
    return re.sub(r'(^\s*(?:file|[a-z_]+_file)\s*=\s*)"([^"]*)"', absolute, text, flags=re.MULTILINE)


def apply_overrides(text: str, overrides: list[str]) -> str:
    """`text` with each KEY=VALUE of `overrides` set: KEY is TABLE.KEY (e.g. materials.granite.density or
    run.end_time; structures[1].element_size for a key of the second [[structures]] table), VALUE a TOML value.
    The key's line in the table is replaced, or added under the table's header; a table the scene does not write
    as a header ([solvers.dem] of a scene that leaves the dem_solver at its defaults) is added at the end (the
    scene check then says whether it may be there). SaboError (exit 2) for a malformed override."""
    lines = text.splitlines()
    for override in overrides:
        key, equals, value = override.partition("=")
        key, value = key.strip(), value.strip()
        if not equals or "." not in key or not value:
            raise SaboError(f"--set {override}: expected TABLE.KEY=VALUE, e.g. --set materials.granite.density=3100",
                            EXIT_BAD_INPUT)
        table, name = key.rsplit(".", 1)
        element = re.fullmatch(r"([A-Za-z0-9_.]+)\[([0-9]+)\]", table)
        if element:  # structures[2]: the third [[structures]] table, as the scene check names it
            array, index = element.group(1), int(element.group(2))
            header = re.compile(rf"^\s*\[\[\s*{re.escape(array)}\s*\]\]\s*(#.*)?$")
            starts = [k for k, line in enumerate(lines) if header.match(line)]
            if index >= len(starts):
                raise SaboError(f"--set {override}: the scene has {len(starts)} [[{array}]] table(s), so "
                                f"{array}[{index}] is none of them; count from 0", EXIT_BAD_INPUT)
            start = starts[index]
        else:
            header = re.compile(rf"^\s*\[\s*{re.escape(table)}\s*\]\s*(#.*)?$")
            start = next((k for k, line in enumerate(lines) if header.match(line)), None)
        if start is None:
            lines += ["", f"[{table}]"]
            start = len(lines) - 1
        end = next((k for k in range(start + 1, len(lines)) if lines[k].lstrip().startswith("[")), len(lines))
        line_of_key = re.compile(rf"^\s*{re.escape(name)}\s*=")
        at = next((k for k in range(start + 1, end) if line_of_key.match(lines[k])), None)
        if at is None:
            lines.insert(start + 1, f"{name} = {value}")
        else:
            lines[at] = f"{name} = {value}"
    return "\n".join(lines) + "\n"
