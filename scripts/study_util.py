"""Helpers shared by the study scripts (family, skin, patch and posture studies)."""
import subprocess
import sys


def run(args):
    """Run a command; return its exit code and its output (stdout and stderr together)."""
    r = subprocess.run(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    return r.returncode, r.stdout


def run_or_exit(args):
    """Run a command; return its output, or end the study with the command and its output."""
    code, out = run(args)
    if code != 0:
        sys.exit(f"failed ({code}): {' '.join(args)}\n{out}")
    return out
