#!/usr/bin/env python3
"""Every `handskin <command> --flag` written in README.md and docs/*.md names a command and flags
that the program has (its own `--help`): a renamed flag left in an example is a doc the code
contradicts.

    python3 scripts/check_doc_commands.py HANDSKIN_BINARY SOURCE_DIR   # exit 1 listing the stale ones

docs/cli.md (made from --help by cli_table.py) is left out: it is checked by the test cli_table.
"""
import glob
import os
import re
import subprocess
import sys

TWO_WORD = {"synth"}  # commands with subcommands: `synth hand`, `synth scan`, ...


def main():
    if len(sys.argv) != 3:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    binary, root = sys.argv[1], sys.argv[2]
    helps = {}

    def flags_of(command):
        if command not in helps:
            r = subprocess.run([binary] + command.split() + ["--help"], capture_output=True, text=True)
            helps[command] = set(re.findall(r"(--[a-z][a-z0-9-]*)", r.stdout)) if r.returncode == 0 else None
        return helps[command]

    files = [os.path.join(root, "README.md")] + sorted(glob.glob(os.path.join(root, "docs", "*.md")))
    stale, seen = [], 0
    line_re = re.compile(r"(?:^|`|\s)(?:\./build/)?handskin ([a-z]+(?: [a-z]+)?)((?: [^`\n]*)?)")
    for path in files:
        if os.path.basename(path) == "cli.md":
            continue
        with open(path, encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                for m in line_re.finditer(line):
                    words = m.group(1).split()
                    command = " ".join(words[:2]) if words[0] in TWO_WORD and len(words) > 1 else words[0]
                    known = flags_of(command)
                    if known is None:
                        # Prose ("handskin turns ...") is not a command line: only a line with
                        # flags claims to be one.
                        if re.search(r"\s--[a-z]", m.group(2)):
                            stale.append(f"{os.path.relpath(path, root)}:{n}: no command '{command}'")
                        continue
                    seen += 1
                    for flag in re.findall(r"(--[a-z][a-z0-9-]*)", m.group(2)):
                        if flag not in known:
                            stale.append(f"{os.path.relpath(path, root)}:{n}: handskin {command} has no {flag}")
    for s in stale:
        print(s)
    print(f"{seen} documented command lines checked, {len(stale)} stale")
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
