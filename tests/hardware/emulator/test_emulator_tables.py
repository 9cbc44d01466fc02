"""Control tables as data: reference-sheet facts, and a cross-check against the SDK's bundled model files."""

from __future__ import annotations

from pathlib import Path

import pytest
from servoface.hardware.emulator import MODELS, EmulatorConfigError, RegisterError, get_model

# (register, address, size) shared by all four models (reference sheet §3)
SHARED = [
    ("Model Number", 0, 2),
    ("Firmware Version", 6, 1),
    ("ID", 7, 1),
    ("Baud Rate", 8, 1),
    ("Return Delay Time", 9, 1),
    ("Drive Mode", 10, 1),
    ("Operating Mode", 11, 1),
    ("Homing Offset", 20, 4),
    ("Moving Threshold", 24, 4),
    ("Temperature Limit", 31, 1),
    ("Max Voltage Limit", 32, 2),
    ("Min Voltage Limit", 34, 2),
    ("PWM Limit", 36, 2),
    ("Velocity Limit", 44, 4),
    ("Max Position Limit", 48, 4),
    ("Min Position Limit", 52, 4),
    ("Shutdown", 63, 1),
    ("Torque Enable", 64, 1),
    ("LED", 65, 1),
    ("Status Return Level", 68, 1),
    ("Registered Instruction", 69, 1),
    ("Hardware Error Status", 70, 1),
    ("Bus Watchdog", 98, 1),
    ("Goal PWM", 100, 2),
    ("Goal Velocity", 104, 4),
    ("Profile Acceleration", 108, 4),
    ("Profile Velocity", 112, 4),
    ("Goal Position", 116, 4),
    ("Realtime Tick", 120, 2),
    ("Moving", 122, 1),
    ("Moving Status", 123, 1),
    ("Present PWM", 124, 2),
    ("Present Velocity", 128, 4),
    ("Present Position", 132, 4),
    ("Present Input Voltage", 144, 2),
    ("Present Temperature", 146, 1),
    ("Indirect Address 1", 168, 2),
]
# model -> (model number, temperature limit, max V, min V, velocity limit, shutdown, present 126 name)
DEFAULTS = {
    "XL330-M288": (1200, 70, 70, 35, 445, 53, "Present Current"),
    "XL430-W250": (1060, 72, 140, 60, 265, 52, "Present Load"),
    "XM430-W350": (1020, 80, 160, 95, 200, 52, "Present Current"),
    "MX-28(2.0)": (30, 80, 160, 95, 230, 52, "Present Load"),  # e-manual MX-28(2.0): Velocity Limit 230
}


@pytest.mark.parametrize("model", sorted(MODELS))
@pytest.mark.parametrize(("name", "address", "size"), SHARED)
def test_shared_addresses(model: str, name: str, address: int, size: int) -> None:
    reg = MODELS[model].table.get(name)
    assert (reg.address, reg.size) == (address, size)
    assert reg.area == ("EEPROM" if address < 64 else "RAM")


@pytest.mark.parametrize("model", sorted(DEFAULTS))
def test_model_defaults(model: str) -> None:
    number, temp, vmax, vmin, vel, shutdown, present = DEFAULTS[model]
    t = MODELS[model].table
    assert t.get("Model Number").default == number
    assert t.get("Temperature Limit").default == temp
    assert (t.get("Max Voltage Limit").default, t.get("Min Voltage Limit").default) == (vmax, vmin)
    assert t.get("Velocity Limit").default == vel
    assert t.get("Shutdown").default == shutdown
    assert t.get(126).name == present and t.get(126).signed
    assert t.get("Return Delay Time").default == 250
    assert t.get("Operating Mode").default == 3
    assert t.get("Status Return Level").default == 2
    assert t.get("Max Position Limit").default == 4095


@pytest.mark.parametrize("model", sorted(MODELS))
def test_access_sign_and_units(model: str) -> None:
    t = MODELS[model].table
    for name in ("Model Number", "Realtime Tick", "Present Position", "Hardware Error Status", "Moving"):
        assert t.get(name).access == "R"
    for name in ("Present Velocity", "Present Position", "Goal Velocity", "Homing Offset", "Goal Position"):
        assert t.get(name).signed
    assert not t.get("Present Input Voltage").signed
    assert t.get("Return Delay Time").unit == "2 us"
    assert t.get("Present Velocity").unit == "0.229 rpm"


def test_current_registers_only_where_documented() -> None:
    assert MODELS["XL330-M288"].table.get("Current Limit").default == 1750
    assert MODELS["XM430-W350"].table.get("Current Limit").default == 1193
    assert "Current Limit" not in MODELS["XL430-W250"].table
    assert "Goal Current" not in MODELS["MX-28(2.0)"].table
    assert MODELS["MX-28(2.0)"].table.get("Acceleration Limit").address == 40


def test_lookup_errors_name_the_key() -> None:
    with pytest.raises(RegisterError, match="Nope"):
        MODELS["XL330-M288"].table.get("Nope")
    with pytest.raises(EmulatorConfigError, match="XL999"):
        get_model("XL999")
    assert get_model("mx-28").name == "MX-28(2.0)"


SDK_TABLES = Path(__file__).resolve().parents[3] / ".venv/lib/python3.11/site-packages/dynamixel_easy_sdk/control_table"
SDK_FILES = {
    "XL330-M288": "xl330_m288_fw52.model",
    "XL430-W250": "xl430_w250.model",
    "XM430-W350": "xm430_w350.model",
    "MX-28(2.0)": "mx_28.model",
}
ALIASES = {"BUS Watchdog": "Bus Watchdog"}


def _sdk_rows(path: Path) -> list[tuple[int, int, str]]:
    rows = []
    in_table = False
    for line in path.read_text().splitlines():
        if line.startswith("["):
            in_table = line.strip() == "[control table]"
            continue
        parts = line.split("\t")
        if in_table and len(parts) == 3 and parts[0].isdigit():
            rows.append((int(parts[0]), int(parts[1]), parts[2].strip()))
    return rows


@pytest.mark.parametrize("model", sorted(SDK_FILES))
def test_agrees_with_sdk_bundled_model_file(model: str) -> None:
    """An independent source: ROBOTIS' own .model files (read as text, not imported)."""
    path = SDK_TABLES / SDK_FILES[model]
    if not path.exists():
        pytest.skip(f"dynamixel_easy_sdk model file {path} not installed")
    table = MODELS[model].table
    rows = _sdk_rows(path)
    assert len(rows) > 40
    for address, size, name in rows:
        if name.startswith("Indirect") and ("Write" in name or "Read" in name):
            continue  # SDK aliases for the indirect blocks
        reg = table.get(ALIASES.get(name, name))
        assert (reg.address, reg.size) == (address, size), name
