"""A section of `make bench` run on its own: ``python -m bench.<section> [--quick]``."""

import argparse
import json


def main(doc, measure, section, argv=None, quick_help=None):
    """Measure (``--quick``: a smaller run), print the raw numbers as JSON and then the
    report's section as markdown; returns the numbers."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help=quick_help)
    args = ap.parse_args(argv)
    from bench.machine import require_compiled_loop

    require_compiled_loop()
    numbers = measure(args.quick)
    print(json.dumps(numbers, indent=1, default=float))
    print("\n".join(section(numbers)))
    return numbers
