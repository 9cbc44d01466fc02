"""Outcomes of a pytest run from its --junitxml report: test name -> (outcome, message + details)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path


def outcomes(report: Path) -> dict[str, tuple[str, str]]:
    out: dict[str, tuple[str, str]] = {}
    for case in ET.parse(report).getroot().iter("testcase"):
        outcome, text = "passed", ""
        for tag in ("failure", "error", "skipped"):
            node = case.find(tag)
            if node is not None:
                outcome = {"failure": "failed", "error": "error", "skipped": "skipped"}[tag]
                text = f"{node.get('message', '')}\n{node.text or ''}"
                break
        out[case.get("name", "")] = (outcome, text)
    return out
