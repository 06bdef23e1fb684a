"""Speed benchmarks, run as ``behavior-hmm bench NAME --json OUT.json`` or ``python -m benchmarks NAME``.

Each module ``benchmarks/<name>.py`` defines ``run(quick: bool = False) -> dict[str, float]``
returning medians (and ratios against a baseline measured in the same run where possible).
"""
