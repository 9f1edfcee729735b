"""Where the name server is: ``yarp.conf``, namespaces and ``YARP_CONFIG_HOME``.

The same files real YARP reads (``NameConfig.cpp``), so ``yarp`` and
``yarp-lite`` tools agree on which server to use:

* the configuration folder is ``$YARP_CONFIG_HOME``, else
  ``$XDG_CONFIG_HOME/yarp``, else ``~/.config/yarp``;
* the namespace (the name server's own port name) is the first word of
  ``$YARP_NAMESPACE``, else of ``yarp_namespace.conf``, else ``/root``;
* the server's address is in ``yarp.conf`` for ``/root`` and in
  ``<namespace with every non-alphanumeric as _>.conf`` otherwise
  (``/robot`` -> ``_robot.conf``), as ``host port [yarp]``.

Two name servers side by side (robot and pilot) are two namespaces, or two
configuration folders.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Optional

from yarp_lite.bottle_text import parse
from yarp_lite.contact import safe_name

DEFAULT_NAMESPACE = "/root"
DEFAULT_PORT = 10000
CONFIG_FILE = "yarp.conf"
NAMESPACE_FILE = "yarp_namespace.conf"


def _env(environ: Optional[Mapping[str, str]]) -> Mapping[str, str]:
    return os.environ if environ is None else environ


def config_home(environ: Optional[Mapping[str, str]] = None) -> Path:
    env = _env(environ)
    if env.get("YARP_CONFIG_HOME"):
        return Path(env["YARP_CONFIG_HOME"])
    if env.get("XDG_CONFIG_HOME"):
        return Path(env["XDG_CONFIG_HOME"]) / "yarp"
    return Path(env.get("HOME", str(Path.home()))) / ".config" / "yarp"


def data_home(environ: Optional[Mapping[str, str]] = None) -> Path:
    env = _env(environ)
    if env.get("YARP_DATA_HOME"):
        return Path(env["YARP_DATA_HOME"])
    if env.get("XDG_DATA_HOME"):
        return Path(env["XDG_DATA_HOME"]) / "yarp"
    return Path(env.get("HOME", str(Path.home()))) / ".local" / "share" / "yarp"


def namespace(environ: Optional[Mapping[str, str]] = None) -> str:
    env = _env(environ)
    text = env.get("YARP_NAMESPACE", "")
    if not text:
        path = config_home(environ) / NAMESPACE_FILE
        text = path.read_text() if path.is_file() else ""
    words = parse(text)
    return str(words[0]) if words and str(words[0]) else DEFAULT_NAMESPACE


def config_file(space: Optional[str] = None, environ: Optional[Mapping[str, str]] = None) -> Path:
    space = space or namespace(environ)
    name = CONFIG_FILE if space == DEFAULT_NAMESPACE else safe_name(space) + ".conf"
    return config_home(environ) / name


@dataclass(frozen=True)
class ServerAddress:
    host: str
    port: int
    mode: str = "yarp"


def parse_config(text: str) -> Optional[ServerAddress]:
    """``NameConfig::fromString``: ``host port [mode]`` or an ini ``[name]`` group."""
    words = text.replace('"', " ").split()
    if not words:
        return None
    if words[0].startswith("["):
        host, port, mode, section = "", 0, "yarp", ""
        for line in text.splitlines():
            line = line.strip()
            if line.startswith("["):
                section = line.strip("[]").strip()
                continue
            parts = line.split()
            if section == "name" and len(parts) >= 2:
                if parts[0] == "host":
                    host = parts[1]
                elif parts[0] == "port" and parts[1].isdigit():
                    port = int(parts[1])
                elif parts[0] == "mode":
                    mode = parts[1]
        return ServerAddress(host, port, mode) if port else None
    if len(words) >= 2 and words[1].lstrip("-").isdigit():
        return ServerAddress(words[0], int(words[1]), words[2] if len(words) > 2 else "yarp")
    return None


def read_server_address(space: Optional[str] = None,
                        environ: Optional[Mapping[str, str]] = None) -> Optional[ServerAddress]:
    path = config_file(space, environ)
    try:
        return parse_config(path.read_text())
    except OSError:
        return None


def write_server_address(address: ServerAddress, space: Optional[str] = None,
                         environ: Optional[Mapping[str, str]] = None) -> Path:
    path = config_file(space, environ)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"{address.host} {address.port} {address.mode}\n")
    return path


def set_namespace(space: str, environ: Optional[Mapping[str, str]] = None) -> Path:
    path = config_home(environ) / NAMESPACE_FILE
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(space + "\n")
    return path
