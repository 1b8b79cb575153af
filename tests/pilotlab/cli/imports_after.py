"""Test helper: run the pilotlab command line, then write every module the process imported.

    python -m tests.pilotlab.cli.imports_after MODULES.json plan recipe.yaml --json

MODULES.json gets sorted(sys.modules) however the command ends (argparse's --help exits).
"""
import json
import sys

from pilotlab.cli import main

if __name__ == "__main__":
    out, argv = sys.argv[1], sys.argv[2:]
    try:
        status = main(argv)
    except SystemExit as done:
        status = done.code
    finally:
        with open(out, "w") as handle:
            json.dump(sorted(sys.modules), handle)
    raise SystemExit(status)
