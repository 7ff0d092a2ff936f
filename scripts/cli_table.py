#!/usr/bin/env python3
"""docs/cli.md: every flag of every command, as a table, from the program's own --help.

    python3 scripts/cli_table.py HANDSKIN_BINARY > docs/cli.md      # write it
    python3 scripts/cli_table.py HANDSKIN_BINARY --check docs/cli.md  # exit 1 when it is stale

The tables are made from CLI11's help text (each command's `--help`), so they cannot drift
from the code: the test `cli_table` runs the check.
"""
import os
import re
import subprocess
import sys

HEADER = """# The command line

Every command and every flag, made from the program's own `--help` by
`python3 scripts/cli_table.py build/handskin > docs/cli.md` (the test `cli_table` fails when
this page is stale).

## Conventions

- **Exit codes**: 0 done; 1 bad data (a file's contents, a key: one line `error: <file or
  key>: <what is wrong>`); 2 bad usage (an unknown command, with the nearest one suggested; an
  unknown option or a missing required one; a flag's value that is not one of its choices or
  not of its form; flags that do not go together; nothing to write: one line
  `error: <flag or command>: <what> (see --help)`); 3 a quality gate failed under `--strict`
  (nothing written); 4 an internal error (a bug). Test
  `Cli.EveryUsageErrorExitsTwoInOneLineNamingItsFlag`.
- **Global flags**, before or after the command: `-q`/`--quiet` (no progress lines on
  stderr; warnings and errors still), `-v`/`--verbose` (each progress line with the process's
  peak memory, and a last line with the command's time and peak memory), `--log-json` (every
  stderr line one JSON object — `{"t", "level": "info"|"warning"|"error", "stage", "message",
  "peak_mb"}`, and `"exit"` on an error — for scripts and GUIs), `--threads N` (the parallel steps on at most N threads; the same bytes with any N),
  `--version`, `-h`/`--help`.
- **Output folders** (`run`, `register`, `skin`, `patches`, `synth …`): checked and locked
  before any work; anything of yours under an output's name is refused (`--force` moves it
  aside); every file is written together or none (docs/architecture.md).
- **A run folder travels**: `report.json` records its inputs relative to itself and absolute
  (`inputs_absolute`), so `patches --skin-dir` works from any working directory, on a moved
  copy too.

- **One name, one meaning** in every command: `--model` is a posture model (hand-posture/1 or
  `builtin:…`; `run` calls the one it puts in skin.glb `--posture-model`), `--skin` a
  `skin.glb` (`pose`, `animate`, `studio`), `--markers` a marker file (`run`, `register`;
  `synth scan --marker-count` is how many), `--png` a picture (`pose`, `solve`), `--size` a
  picture's width in px (1024 by default; `pose`'s pictures are square, `render`'s 4:3), a
  flag `--no-…` turns off what is on by default.
"""

OPTION = re.compile(r"^  (\S.*?)(?:\s{2,}(.*))?$")


def help_of(binary, words):
    out = subprocess.run([binary, *words, "--help"], capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"error: {' '.join(words)} --help exited {out.returncode}")
    # Defaults inside the build folder (the studio's page) are written as <build>/…, so that
    # the page does not depend on where the tree was built.
    return out.stdout.replace(os.path.dirname(os.path.abspath(binary)), "<build>")


def sections(text):
    """{section name: [lines]} of a CLI11 help text; the first line is the description."""
    out, name = {"": []}, ""
    for line in text.splitlines():
        if line and not line.startswith(" ") and line.endswith(":"):
            name = line[:-1]
            out[name] = []
        else:
            out.setdefault(name, []).append(line)
    return out


def options(lines):
    """(flag, type and default, description) rows; a description may run on the next line."""
    rows = []
    for line in lines:
        if not line.strip():
            continue
        if line.startswith("      ") and rows:  # the description on a line of its own
            rows[-1][2] = (rows[-1][2] + " " + line.strip()).strip()
            continue
        m = OPTION.match(line)
        if not m:
            continue
        spec, desc = m.group(1).strip(), (m.group(2) or "").strip()
        flag, _, kind = spec.partition(" ")
        rows.append([flag, kind.strip(), desc])
    return rows


def subcommands(lines):
    return [line.split()[0] for line in lines if line.startswith("  ") and line.strip()]


def cell(s, code=False):
    s = s.replace("|", "\\|")
    return s if code else s.replace("<", "&lt;").replace(">", "&gt;")


def table(binary, words, depth, out):
    text = help_of(binary, words)
    sec = sections(text)
    description = next((l for l in sec[""] if l.strip()), "")
    out.append(f"{'#' * depth} `handskin {' '.join(words)}`".rstrip() if words else f"{'#' * depth} `handskin`")
    out.append("")
    if description and words:
        out.append(description.strip())
        out.append("")
    rows = options(sec.get("Options", []))
    if rows:
        out.append("| flag | value (= default) | meaning |")
        out.append("|---|---|---|")
        for flag, kind, desc in rows:
            out.append(f"| `{cell(flag, True)}` | {('`' + cell(kind, True) + '`') if kind else ''} | {cell(desc)} |")
        out.append("")
    for sub in subcommands(sec.get("Subcommands", [])):
        table(binary, [*words, sub], min(depth + 1, 4), out)


def main():
    if len(sys.argv) not in (2, 4) or (len(sys.argv) == 4 and sys.argv[2] != "--check"):
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    out = [HEADER]
    table(sys.argv[1], [], 2, out)
    page = "\n".join(out).rstrip() + "\n"
    if len(sys.argv) == 4:
        with open(sys.argv[3], encoding="utf-8") as f:
            if f.read() != page:
                print(f"error: {sys.argv[3]} is stale: run python3 scripts/cli_table.py <handskin> > {sys.argv[3]}",
                      file=sys.stderr)
                return 1
        return 0
    sys.stdout.write(page)
    return 0


if __name__ == "__main__":
    sys.exit(main())
