"""HAL configuration: how joints are grouped into chains, and rates.

The grouping is what the team changed 15 days before the DRC; modules never
see it because the whole-body interface asks the HAL for it at run time.
Two groupings ship in ``models/``: ``hal_chains.ini`` (one chain per limb, as
YARP's control boards) and ``hal_whole_body.ini`` (one chain for all 33
joints).  Any other grouping of the 33 joints works.

File format (YARP ini style)::

    robot walkman
    period_ms 2           # state streaming period
    [chains]
    torso WaistLat WaistSag WaistYaw
    head NeckYawj NeckPitchj
    ...
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional

from walkman.gym.inifile import IniError, parse_ini
from walkman.model.description import CHAINS, Robot, walkman


@dataclass
class HalConfig:
    robot: str = "walkman"
    period_ms: float = 2.0
    chains: Dict[str, List[str]] = field(default_factory=dict)

    def validate(self, model: Robot, where: str = "HAL configuration") -> None:
        seen: Dict[str, str] = {}
        known = set(model.joint_names)
        for chain, joints in self.chains.items():
            if not joints:
                raise IniError(f"{where}: chain {chain!r} has no joints")
            for joint in joints:
                if joint not in known:
                    raise IniError(f"{where}: chain {chain!r} lists unknown joint {joint!r}")
                if joint in seen:
                    raise IniError(f"{where}: joint {joint!r} is in chains {seen[joint]!r} "
                                   f"and {chain!r}")
                seen[joint] = chain
        missing = [name for name in model.joint_names if name not in seen]
        if missing:
            raise IniError(f"{where}: joints in no chain: {', '.join(missing)}")
        if not 0.5 <= self.period_ms <= 1000:
            raise IniError(f"{where}: period_ms must be between 0.5 and 1000, got {self.period_ms}")


def default_config(model: Optional[Robot] = None) -> HalConfig:
    model = model or walkman()
    return HalConfig(chains={chain: [j.name for j in model.chain(chain)] for chain in CHAINS})


def load_config(path: Optional[Path], model: Optional[Robot] = None) -> HalConfig:
    model = model or walkman()
    if path is None:
        config = default_config(model)
    else:
        sections = parse_ini(Path(path).read_text(), str(path))
        top = sections.get("", {})
        config = HalConfig(robot=str(top.get("robot", ["walkman"])[0]),
                           period_ms=float(top.get("period_ms", [2.0])[0]),
                           chains={name: [str(v) for v in values]
                                   for name, values in sections.get("chains", {}).items()})
    config.validate(model, str(path) if path else "default HAL configuration")
    return config
