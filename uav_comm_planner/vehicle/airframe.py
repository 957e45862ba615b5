"""Airframes by name or by file: the propulsion model of the vehicle that carries the radio.

An airframe file is YAML with the units in its keys, the fields of
:class:`~uav_comm_planner.core.propulsion.Airframe`::

    name: my-quad
    blade_profile_power_w: 79.86
    induced_power_w: 88.63
    tip_speed_mps: 120.0
    induced_velocity_mps: 4.03
    fuselage_drag_ratio: 0.6
    air_density_kg_per_m3: 1.225
    rotor_solidity: 0.05
    rotor_disc_area_m2: 0.503
    top_airspeed_mps: 30.0
    climb_w_per_mps: 0.0        # optional
    descent_w_per_mps: 0.0      # optional

A ``source`` key (free text: where the numbers come from) is allowed and ignored. Named
airframes: ``zeng2019`` (Zeng, Xu and Zhang 2019, Table I) and the files of this package's
``airframes/`` folder by their stem (``arducopter-sitl-quad``: ArduCopter SITL's default quad,
measured on it).
"""

from __future__ import annotations

import dataclasses
from importlib import resources
import os
from pathlib import Path

import yaml

from uav_comm_planner.core.propulsion import Airframe, ZENG2019
from uav_comm_planner.errors import InvalidScenarioError

#: Airframe files larger than this are refused before they are read.
MAX_AIRFRAME_BYTES = 64 * 1024
#: The airframe ArduPilot missions are planned with when none is named.
DEFAULT_ARDUPILOT_AIRFRAME = 'arducopter-sitl-quad'
_FIELDS = {field.name for field in dataclasses.fields(Airframe)}
_OPTIONAL = {'climb_w_per_mps', 'descent_w_per_mps'}


def packaged_airframes() -> dict[str, resources.abc.Traversable]:
    """The airframe files shipped with the package, by name (file stem, '_' as '-')."""
    folder = resources.files('uav_comm_planner.vehicle') / 'airframes'
    return {entry.name[:-len('.yaml')].replace('_', '-'): entry
            for entry in folder.iterdir() if entry.name.endswith('.yaml')}


def airframe_names() -> list[str]:
    """Every airframe that :func:`airframe_named` knows."""
    return sorted({ZENG2019.name, *packaged_airframes()})


def airframe_from_mapping(data: object, origin: str) -> Airframe:
    """An :class:`Airframe` from a parsed airframe file; ``origin`` names it in errors."""
    if not isinstance(data, dict):
        raise InvalidScenarioError(f'{origin}: an airframe file is a mapping of its fields '
                                   f'({", ".join(sorted(_FIELDS))})')
    unknown = set(data) - _FIELDS - {'source'}
    if unknown:
        raise InvalidScenarioError(f'{origin}: unknown keys {sorted(map(str, unknown))}; an '
                                   f'airframe has {sorted(_FIELDS)} (units in the names)')
    missing = _FIELDS - _OPTIONAL - set(data)
    if missing:
        raise InvalidScenarioError(f'{origin}: missing {sorted(missing)}')
    try:
        return Airframe(**{key: value for key, value in data.items() if key != 'source'})
    except InvalidScenarioError as exc:
        raise InvalidScenarioError(f'{origin}: {exc}') from None


def load_airframe(path: str | os.PathLike) -> Airframe:
    """The airframe of a YAML file (module docstring); a typed error for a missing, large or
    malformed file."""
    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise InvalidScenarioError(f'airframe file {path}: {exc.strerror or exc}') from None
    if size > MAX_AIRFRAME_BYTES:
        raise InvalidScenarioError(f'airframe file {path}: {size} bytes, at most '
                                   f'{MAX_AIRFRAME_BYTES} accepted')
    try:
        text = path.read_text(encoding='utf-8')
        data = yaml.safe_load(text)
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise InvalidScenarioError(f'airframe file {path}: not readable YAML '
                                   f'({str(exc).splitlines()[0]})') from None
    return airframe_from_mapping(data, f'airframe file {path}')


def airframe_named(name_or_path: str | os.PathLike) -> Airframe:
    """An airframe by name (:func:`airframe_names`) or by the path of its file."""
    text = os.fspath(name_or_path)
    if text == ZENG2019.name:
        return ZENG2019
    packaged = packaged_airframes()
    if text in packaged:
        data = yaml.safe_load(packaged[text].read_text(encoding='utf-8'))
        return airframe_from_mapping(data, f'airframe {text!r}')
    if text.endswith(('.yaml', '.yml')) or os.sep in text or Path(text).exists():
        return load_airframe(text)
    raise InvalidScenarioError(f'unknown airframe {text!r}: name one of {airframe_names()} or '
                               f'give the path of a YAML file')


def default_airframe(firmware: str) -> Airframe | None:
    """The airframe a mission for ``firmware`` is planned with when none is named: ArduCopter
    SITL's quad for ArduPilot (once its measured file ships with the package), none for PX4."""
    if firmware == 'ardupilot' and DEFAULT_ARDUPILOT_AIRFRAME in packaged_airframes():
        return airframe_named(DEFAULT_ARDUPILOT_AIRFRAME)
    return None


def airframe_yaml(airframe: Airframe, source: str = '') -> str:
    """The YAML text of an airframe file (:func:`load_airframe` reads it back)."""
    data = dataclasses.asdict(airframe)
    if source:
        data['source'] = source
    return yaml.safe_dump(data, sort_keys=False)


__all__ = ['airframe_from_mapping', 'airframe_named', 'airframe_names', 'airframe_yaml',
           'DEFAULT_ARDUPILOT_AIRFRAME', 'default_airframe', 'load_airframe', 'MAX_AIRFRAME_BYTES',
           'packaged_airframes']
