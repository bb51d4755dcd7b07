"""TOML drive description -> frozen, validated dataclasses.

Every error is a `ConfigError` naming the file and the dotted key path, e.g.
``drive.toml: pulleys[1].radius: must be > 0, got -0.05``. Overrides (``--set KEY=VALUE``) are
applied to the parsed TOML before validation; VALUE is parsed as a TOML literal (never eval), a bare
word being taken as a string. Units are SI everywhere; keys carry no unit suffixes.

One declaration: each dataclass below is the schema of its TOML table. A field declared with
``key(KIND, default, doc=..., units=...)`` is a TOML key of that name; KIND checks and converts the
TOML value (`parse`) and writes it back (`dump`). Parsing (unknown keys with the closest valid key
suggested, missing keys, type and range errors with the key path), the defaults, `valid_keys`,
`key_docs` and the resolved TOML (`config_to_dict`, `resolved_toml`) are all derived from these
declarations. Checks that involve several keys (one adjustable pulley, slide_range only on slides,
the default tension mode, the transient's cross-checks, the CSV load tables, ...) are explicit code
after the generic parse, in `config_from_dict`.

The package by job: `kinds` (the value kinds, `key()`, the generic parse and dump of a declared table
and the checker with its key-path errors), `schema` (the declarations, one dataclass per table, and
the keys derived from them), `overrides` (reading the TOML and ``--set``), `checks` (the checks of
several keys), `tables` (the CSV load tables), `load` (`load_config`, `config_from_dict`) and
`resolved` (the resolved TOML, its hash, overrides on a loaded config).

Public API (`__all__`): the schema's dataclasses, the constants of its choices, `key` and `replace`
for declaring and deriving configs, and the functions below; `from beltdyn.config import X` is the way
to reach them (the modules are the package's inside).
"""

from dataclasses import replace

from beltdyn.config.kinds import (AXIAL_LAWS, CURVATURES, DEFAULT_STEP, MAX_GAUSS_POINTS, SIDES, SPAN_MODELS,
                                  SUPPORTS, TENSION_MODES, WRAP_MODELS, key)
from beltdyn.config.load import config_from_dict, load_config
from beltdyn.config.overrides import apply_override, parse_toml_file
from beltdyn.config.resolved import config_hash, config_to_dict, resolved_toml, with_overrides
from beltdyn.config.schema import (Belt, Damping, Decoupler, DriveConfig, KeyDoc, Load, Mesh, ModalOptions, ModelOptions, Pulley,
                                   Record, ResponseExcitation, ResponseOptions, Rotation, RunningOptions, Signal,
                                   SpanSetting, SpectrumOptions, StaticOptions, StaticTorque, SweepTable, Tension,
                                   TransientOptions, key_docs, resolved_spans, span_name_key, span_names, valid_keys)
from beltdyn.config.tables import table_bytes

__all__ = [
    "Belt", "Pulley", "Decoupler", "Tension", "Mesh", "SpanSetting", "ModelOptions", "StaticTorque", "StaticOptions", "ModalOptions",
    "Signal", "Rotation", "Load", "Record", "Damping", "ResponseExcitation", "ResponseOptions", "SpectrumOptions",
    "TransientOptions", "RunningOptions", "SweepTable", "DriveConfig", "KeyDoc",
    "AXIAL_LAWS", "CURVATURES", "DEFAULT_STEP", "MAX_GAUSS_POINTS", "SIDES", "SPAN_MODELS", "SUPPORTS", "TENSION_MODES", "WRAP_MODELS",
    "load_config", "config_from_dict", "config_to_dict", "resolved_toml", "config_hash", "apply_override",
    "parse_toml_file", "with_overrides", "valid_keys", "key_docs", "key", "replace", "resolved_spans", "span_name_key", "span_names",
    "table_bytes",
]
