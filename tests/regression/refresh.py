"""Recompute the regression references from sample_data/ and rewrite them, on purpose.

    .venv/bin/python tests/regression/refresh.py            # every artifact
    .venv/bin/python tests/regression/refresh.py fit-red-goniochromatic render-print-small
    .venv/bin/python tests/regression/refresh.py --list     # the names
    .venv/bin/python tests/regression/refresh.py --check    # compare only, write nothing

Uses the very functions the tests use (gonio_regression.ARTIFACTS), prints for each
artifact what changed and by how much against the old reference, then writes the new one
and the manifest (inputs with sha256, tolerances). Refresh only for an intended change and
say why in the commit message (README.md in this folder).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import gonio_regression as reg  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", metavar="NAME", help="artifacts (default: all)")
    parser.add_argument("--list", action="store_true", help="list the artifacts and exit")
    parser.add_argument("--check", action="store_true", help="compare only; write nothing")
    args = parser.parse_args(argv)
    if args.list:
        for a in reg.ARTIFACTS.values():
            print(f"{a.name:28s} {a.kind:8s} {reg.tolerance_text(a)}")
        return 0
    unknown = [n for n in args.names if n not in reg.ARTIFACTS]
    if unknown:
        print(f"refresh.py: error: unknown artifact(s) {', '.join(unknown)}; "
              f"valid: {', '.join(reg.ARTIFACTS)}", file=sys.stderr)
        return 2
    wanted = set(args.names or reg.ARTIFACTS)
    # an artifact computed from another's stored reference is stale once that one moves
    for a in reg.ARTIFACTS.values():
        if set(a.depends) & wanted and a.name not in wanted:
            print(f"note: also {a.name} (it reads the {', '.join(a.depends)} reference)")
            wanted.add(a.name)
    # registry order: lobes-basis before the lobe weights that read its stored exponents
    todo = [a for a in reg.ARTIFACTS.values() if a.name in wanted]
    manifest = reg.read_manifest()
    failed = 0
    for a in todo:
        value = a.compute()
        try:
            old = reg.load(a)
        except FileNotFoundError:
            old = None
        if old is None:
            print(f"{a.name}: new reference")
        else:
            checks = reg.compare(a, value, old)
            ok = all(c.ok for c in checks)
            failed += not ok
            print(f"{a.name}: {'within tolerance' if ok else 'OUTSIDE tolerance'}")
            for c in checks:
                print("    " + c.line())
        if not args.check:
            reg.save(a, value)
            manifest[a.name] = reg.manifest_entry(a)
    if not args.check:
        reg.write_manifest({k: v for k, v in manifest.items() if k in reg.ARTIFACTS})
        size = sum(p.stat().st_size for p in reg.REFERENCES.iterdir())
        print(f"wrote {len(todo)} reference(s) to {reg.REFERENCES.relative_to(reg.ROOT)}/ "
              f"({size / 1e6:.2f} MB in all)")
    return 1 if (args.check and failed) else 0


if __name__ == "__main__":
    sys.exit(main())
