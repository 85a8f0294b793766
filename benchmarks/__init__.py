"""Research scripts: measurements and studies run by hand, not user commands (those are `mixvi`'s,
in problems.commands). Run one as `python benchmarks/NAME.py` or `python -m benchmarks.NAME` from
the repository; each prints a table and most write JSON (docs/benchmarks.md lists the commands
beside their numbers). Not installed with the packages, and imported by none of vi_core, fem and
problems (tests/test_layout.py)."""
