"""The strategy registry: name -> (frozen, versioned config dataclass, handler named by string).

A strategy is two modules, as a job kind is (docs/CONVENTIONS.md): its config, which planning
imports for the strategy's name and options, and its handler, imported only when the strategy is
applied:

    # pilotlab/strategies/configs/prune.py: imported to plan, so it imports nothing heavy
    @dataclass(frozen=True)
    class LocalPruneConfig:
        version: int = 1             # bump it when the handler's output changes for the same options
        conv: float = 0.3

    register_strategy("local_prune", LocalPruneConfig, "pilotlab.strategies.prune:local_prune")

    # pilotlab/strategies/prune.py: imported by `apply_strategy` only, so torch at its top
    import torch
    from pilotlab.strategies.apply import StrategySource

    def local_prune(config: LocalPruneConfig, source: StrategySource) -> dict:
        model = source.load_model()          # a fresh copy of the trained checkpoint
        ...                                  # write the artifact into source.out
        source.write(source.meta(format="onnx", file="model.onnx", runtime="onnxruntime", dtype="fp32"))
        return {"sparsity": 0.4}             # strategy-specific results

`hardware_dependent=True` says the artifact depends on the target hardware (fp16, tensorrt): the
planner then makes one optimize job per target device. `takes_onnx=True` says the handler works on
the ONNX graph, so it also runs on a user's `onnx:` model. `requires=` names the optional packages
the handler needs (found without importing them) and `extra=` the pip extra that installs them:
where one is missing the strategy is "not applicable: it needs X, not installed here (pip install -e
'.[extra]')" and its handler module, which imports them at its top, is never imported.

Options come from the recipe's `strategies:` section; an unknown option is an error naming the
strategy and its known options. Every handler starts from the checkpoint on disk, so no strategy
ever sees another one's changes. A strategy that cannot run on the target hardware raises
`matrix.NotApplicable(reason)`.

The code of an optimize job is its strategy's handler module and config module with what they
import within pilotlab (`pilotlab.specs.optimize`), so editing one strategy reruns only its jobs.
Planning imports every config module and no handler: `pilotlab plan` stays quick
(tests/pilotlab/cli/test_light_imports.py). What a handler is given, `StrategySource`, and
`apply_strategy` are the run side, in pilotlab/strategies/apply.py (they need numpy and the frames):
this module holds only names, configs and handler names.
"""
from __future__ import annotations

import dataclasses
import importlib
import importlib.util
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import Any

from matrix.kinds import NotApplicable
from matrix.registry import Registry
from pilotlab.specs.base import build_config
from pilotlab.strategies.configs.prepare import PREPARATIONS, PreparationEntry


Handler = Callable[[Any, Any], dict]   # (config, pilotlab.strategies.apply.StrategySource) -> its figures


@dataclass(frozen=True, eq=False)
class StrategyEntry:
    name: str
    config_cls: type
    target: str | Handler            # "package.module:function", imported when the strategy is applied
    hardware_dependent: bool = False  # its artifact depends on the target device (one job per device)
    takes_onnx: bool = False         # it works on the ONNX graph, so it runs on a user's onnx: model too
    requires: tuple[str, ...] = ()   # optional packages its handler imports (checked before it is imported)
    extra: str = ""                  # the pip extra that installs them
    prepared_by: str = ""            # the preparation whose network it converts (configs/prepare.py), if any

    @property
    def module(self) -> str:
        """The handler's module."""
        return self.target.partition(":")[0] if isinstance(self.target, str) else self.target.__module__

    @property
    def modules(self) -> tuple[str, ...]:
        """The modules that implement it, the roots of its code fingerprint: the handler's and the config's."""
        return tuple(dict.fromkeys((self.module, self.config_cls.__module__)))

    @cached_property
    def handler(self) -> Handler:
        if not isinstance(self.target, str):
            return self.target
        module, _, function = self.target.partition(":")
        return getattr(importlib.import_module(module), function)

    @property
    def version(self) -> int:
        return self.config_cls().version

    @property
    def options(self) -> list[str]:
        return [f.name for f in dataclasses.fields(self.config_cls) if f.name != "version"]

    @property
    def missing(self) -> list[str]:
        """The packages the handler needs that are not installed here (found without importing them)."""
        return [name for name in self.requires if importlib.util.find_spec(name) is None]

    def check_installed(self) -> None:
        """NotApplicable unless every package the handler needs is installed here (found without
        importing it: its handler module imports them at its top, and is then never imported)."""
        if absent := self.missing:
            install = f" (pip install -e '.[{self.extra}]')" if self.extra else ""
            raise NotApplicable(f"{self.name} needs {', '.join(absent)}, not installed here{install}")


STRATEGIES: Registry[StrategyEntry] = Registry("strategy")


def register_strategy(name: str, config_cls: type, handler: str | Handler, *, hardware_dependent: bool = False,
                      takes_onnx: bool = False, requires: tuple[str, ...] = (), extra: str = "",
                      prepared_by: str = "") -> StrategyEntry:
    """Register strategy `name`: its config class and its handler, "package.module:function" (or the
    function itself); `prepared_by`: the preparation (pilotlab.strategies.configs.prepare) whose network
    the handler converts, its options among the config's."""
    if not (dataclasses.is_dataclass(config_cls) and config_cls.__dataclass_params__.frozen):
        raise TypeError(f"strategy {name!r}: its config must be a frozen dataclass")
    if "version" not in {f.name for f in dataclasses.fields(config_cls)}:
        raise TypeError(f"strategy {name!r}: its config needs a `version` field")
    if isinstance(handler, str) and not all(handler.partition(":")[::2]):
        raise TypeError(f"strategy {name!r}: its handler {handler!r} is not \"package.module:function\"")
    if prepared_by:
        fields = {f.name for f in dataclasses.fields(config_cls)}
        needed = [f.name for f in dataclasses.fields(PREPARATIONS.get(prepared_by).config_cls)]
        if missing := [name for name in needed if name not in fields]:
            raise TypeError(f"strategy {name!r}: prepared by {prepared_by}, its config needs the options {missing}")
    return STRATEGIES.add(name, StrategyEntry(name, config_cls, handler, hardware_dependent, takes_onnx,
                                              tuple(requires), extra, prepared_by))


def preparation_for(name: str, config) -> tuple[PreparationEntry, Any] | None:
    """(the preparation, its config) of strategy `name` with `config`; None for a strategy that prepares
    no shared network."""
    entry = STRATEGIES.get(name)
    if not entry.prepared_by:
        return None
    preparation = PREPARATIONS.get(entry.prepared_by)
    return preparation, preparation.config_from(config)


def make_strategy_config(name: str, options: dict[str, Any] | None = None):
    """The strategy's config from recipe options; unknown options and wrong types are errors."""
    return build_config(STRATEGIES.get(name).config_cls, options, f"strategies.{name}")


def full_options(name: str, options: dict[str, Any] | None = None) -> dict[str, Any]:
    """Every option of the strategy's config, the recipe's where it gives one and the defaults elsewhere
    (version left out: the code's own): what an optimize job is keyed by, so writing out a default, or
    leaving it out, plans the same job."""
    config = make_strategy_config(name, options)
    return {field.name: getattr(config, field.name) for field in dataclasses.fields(config) if field.name != "version"}
