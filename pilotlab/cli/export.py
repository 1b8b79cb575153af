"""`pilotlab export KEY --out DIR`: copy an optimized artifact out of the store, with a README."""
from __future__ import annotations

import argparse
from pathlib import Path


def register(subparsers) -> None:
    parser = subparsers.add_parser("export", help="copy an optimized artifact out of the job store",
                                   description=__doc__)
    parser.add_argument("key", help="the optimize job's key (a unique prefix is enough)")
    parser.add_argument("--out", required=True, type=Path, help="folder to create")
    parser.add_argument("--store", help="job store folder (default: $PILOTLAB_STORE, else .pilotlab)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from matrix.engine import open_store
    from pilotlab.domain import DOMAIN
    from pilotlab.export import export_job
    out = export_job(open_store(DOMAIN, args.store), args.key, args.out)
    print(f"exported to {out} (see {out / 'README.md'})")
    return 0
