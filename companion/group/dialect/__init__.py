"""The patrol group's MAVLink dialect (``patrol.xml``) as a Python module, built on import.

The module is generated from the XML next to this file by pymavlink's own generator
(``mavgen``, Python 3, wire protocol 2.0) into a temporary directory and loaded from there,
once per process (about 50 ms). Nothing is cached on disk, so the module always matches the
XML and the installed pymavlink, works from a fresh ``pip install -e .`` or a wheel with no
network, and needs no writable directory beyond the system's temporary one.

Use it as ``from companion.group.dialect import patrol`` (``patrol.MAVLink``,
``patrol.MAVLink_patrol_state_message``, ``patrol.PATROL_MODE_PATROL``, ...).
"""

from __future__ import annotations

import contextlib
import importlib.util
import io
import sys
import tempfile
from pathlib import Path
from types import ModuleType

from pymavlink.generator import mavgen

__all__ = ["MODULE_NAME", "XML_PATH", "generate", "patrol"]

XML_PATH = Path(__file__).with_name("patrol.xml")
MODULE_NAME = "companion.group.dialect.patrol"


class DialectError(RuntimeError):
    """``patrol.xml`` could not be turned into a module (a packaging bug, not user input)."""


def generate(xml_path: Path = XML_PATH, *, validate: bool = False) -> ModuleType:
    """Generate and import the Python module of a MAVLink 2 dialect XML file.

    Args:
        xml_path: the dialect (it may include others from its own directory).
        validate: also check the XML against MAVLink's schema (needs lxml).

    Returns:
        The imported module, registered in ``sys.modules`` as :data:`MODULE_NAME` when
        ``xml_path`` is this package's ``patrol.xml``.
    """
    with tempfile.TemporaryDirectory(prefix="patrol-dialect-") as tmp:
        out = Path(tmp) / "patrol.py"
        opts = mavgen.Opts(str(out), wire_protocol="2.0", language="Python3", validate=validate)
        log = io.StringIO()
        with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
            ok = mavgen.mavgen(opts, [str(xml_path)])
        if not ok or not out.exists():
            raise DialectError(f"mavgen failed on {xml_path}:\n{log.getvalue()}")
        name = MODULE_NAME if xml_path == XML_PATH else f"_mavgen_{xml_path.stem}"
        spec = importlib.util.spec_from_file_location(name, out)
        if spec is None or spec.loader is None:
            raise DialectError(f"cannot import the module generated from {xml_path}")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return module


patrol: ModuleType = sys.modules.get(MODULE_NAME) or generate()
