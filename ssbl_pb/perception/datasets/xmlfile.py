"""Reading the PETS 2009 XML files (annotations, calibrations) with errors that name the file and format."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from ...errors import UserError


def xml_root(path: Path, error: type[UserError], expected: str, what: str = "file") -> ET.Element:
    """The root element of ``path``; ``error`` naming the file and ``expected`` if it is missing or not XML."""
    if not path.is_file():
        raise error(f"{path}: {what} not found; expected {expected}")
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise error(f"{path}: not valid XML ({exc}); expected {expected}") from exc
