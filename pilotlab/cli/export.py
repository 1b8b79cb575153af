"""`pilotlab export KEY --out DIR`: copy an optimized artifact out of the store, with a README."""
from __future__ import annotations

import argparse
import os
from pathlib import Path


def register(subparsers) -> None:
    parser = subparsers.add_parser("export", help="copy an optimized artifact out of the job store",
                                   description=__doc__)
    parser.add_argument("key", help="the optimize job's key (a unique prefix is enough)")
    parser.add_argument("--out", required=True, type=Path, help="folder to create")
    parser.add_argument("--store", type=Path, default=None,
                        help="job store (default: $PILOTLAB_STORE or .pilotlab)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pilotlab.export import export_job
    store = args.store or Path(os.environ.get("PILOTLAB_STORE", ".pilotlab"))
    out = export_job(store, args.key, args.out)
    print(f"exported to {out} (see {out / 'README.md'})")
    return 0
