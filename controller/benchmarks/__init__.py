"""Benchmarks behind `servoface bench` / `make bench`: each suite module yields `Figure`s.

Suites: ``bus`` (hardware), ``face`` (muscle model, rendering), ``gate`` (twin gate, TSS), ``pipeline``
(end to end), ``timeline`` (sampling cost).
Each suite module defines ``run(quick: bool = False) -> Iterator[Figure]``.
"""

SUITES: dict[str, str] = {
    "bus": "controller.benchmarks.bus",
    "face": "controller.benchmarks.face",
    "gate": "controller.benchmarks.gate",
    "pipeline": "controller.benchmarks.pipeline",
    "timeline": "controller.benchmarks.timeline",
}
