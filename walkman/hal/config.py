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
    [arbitration]         // two modules commanding one joint (walkman/hal/arbitration.py)
    policy refuse         // refuse, priority or share
    release_after 0.5     // s of silence after which a module's joints are free
    priority walking 1 drc_door 2
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional

from walkman.inifile import IniError, parse_ini
from walkman.hal.arbitration import POLICIES
from walkman.model.description import CHAINS, Robot, walkman


@dataclass
class HalConfig:
    robot: str = "walkman"
    period_ms: float = 2.0
    chains: Dict[str, List[str]] = field(default_factory=dict)
    policy: str = "refuse"
    release_after: float = 0.5
    priorities: Dict[str, int] = field(default_factory=dict)

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
        if self.policy not in POLICIES:
            raise IniError(f"{where}: [arbitration] policy must be one of {', '.join(POLICIES)}, "
                           f"got {self.policy!r}")
        if not 0.01 <= self.release_after <= 60:
            raise IniError(f"{where}: [arbitration] release_after must be 0.01..60 s, "
                           f"got {self.release_after}")


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
        _arbitration(config, sections.get("arbitration", {}), str(path))
    config.validate(model, str(path) if path else "default HAL configuration")
    return config


def _arbitration(config: HalConfig, section: Dict[str, list], where: str) -> None:
    for key, values in section.items():
        if key == "policy" and len(values) == 1:
            config.policy = str(values[0])
        elif key == "release_after" and len(values) == 1:
            try:
                config.release_after = float(values[0])
            except ValueError:
                raise IniError(f"{where}: [arbitration] release_after must be a number, "
                               f"got {values[0]!r}") from None
        elif key == "priority" and values and len(values) % 2 == 0:
            for name, value in zip(values[::2], values[1::2]):
                if isinstance(value, bool) or not isinstance(value, int):
                    raise IniError(f"{where}: [arbitration] priority of {name} must be an "
                                   f"integer, got {value!r}")
                config.priorities[str(name)] = value
        else:
            raise IniError(f"{where}: [arbitration] does not understand {key} "
                           f"{' '.join(map(str, values))} (policy P, release_after S, "
                           f"priority MODULE N ...)")
