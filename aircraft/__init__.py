"""Airframes: one folder per airframe with its JSBSim XML (engine/, systems/), model card,
flight controller and gains file."""

from pathlib import Path

AIRCRAFT_DIR = Path(__file__).resolve().parent


def airframe_dir(name: str) -> Path:
    """Folder of one of this project's airframes (``aircraft/<name>/``)."""
    return AIRCRAFT_DIR / name
