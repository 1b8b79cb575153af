"""`pilotlab strategy list | show NAME`: the optimization strategies and their options, read from their
configs (pilotlab/strategies/configs: each option's type, default and the comment beside it), so what
is shown is what a recipe's `strategies:` section takes."""
from __future__ import annotations

import argparse
import dataclasses
import inspect
import re
import typing
from dataclasses import dataclass


def register(subparsers) -> None:
    parser = subparsers.add_parser("strategy", help="list the optimization strategies and their options",
                                   description="The optimization strategies a recipe's matrix can name, and the "
                                               "options its strategies: section can give them "
                                               "(`my_prune: {use: local_prune, conv: 0.5}`).")
    commands = parser.add_subparsers(dest="strategy_command", metavar="COMMAND", required=True)
    listing = commands.add_parser("list", help="every strategy with its options")
    listing.set_defaults(func=list_strategies)
    show = commands.add_parser("show", help="one strategy's options: type, default and what each does")
    show.add_argument("name", help="a strategy's name (pilotlab strategy list)")
    show.set_defaults(func=show_strategy)


@dataclass(frozen=True)
class Option:
    name: str
    type: str
    default: str
    comment: str


def options_of(config_cls: type) -> list[Option]:
    """A strategy config's options (every field but its version), with the comment beside each field
    in the source of the class that declares it."""
    hints, comments = typing.get_type_hints(config_cls), _field_comments(config_cls)
    return [Option(field.name, _type_name(hints[field.name]), _default(field), comments.get(field.name, ""))
            for field in dataclasses.fields(config_cls) if field.name != "version"]


_FIELD = re.compile(r"^\s+(\w+)\s*:[^=#]*=[^#]*#\s*(.+?)\s*$")


def _field_comments(config_cls: type) -> dict[str, str]:
    """field -> the comment on its line, the nearest class in the MRO first (a subclass may re-comment)."""
    comments: dict[str, str] = {}
    for cls in reversed(config_cls.__mro__[:-1]):
        try:
            lines = inspect.getsource(cls).splitlines()
        except (OSError, TypeError):
            continue
        comments |= {m[1]: m[2] for line in lines if (m := _FIELD.match(line))}
    return comments


def _type_name(annotation) -> str:
    if typing.get_origin(annotation) is typing.Literal:
        return " | ".join(str(value) for value in typing.get_args(annotation))
    text = getattr(annotation, "__name__", None) if not typing.get_args(annotation) else None
    return text or str(annotation).replace("typing.", "")


def _default(field: dataclasses.Field) -> str:
    if field.default is not dataclasses.MISSING:
        return str(field.default)
    if field.default_factory is not dataclasses.MISSING:
        return str(field.default_factory())
    return "(required)"


def list_strategies(args: argparse.Namespace) -> int:
    from rich.table import Table
    from rich.text import Text
    from matrix.display import console as wide_console
    from pilotlab.strategies import STRATEGIES
    table = Table("strategy", "options (default)", "needs", title="strategies")
    for name, entry in sorted(STRATEGIES.items()):
        options = ", ".join(f"{o.name}={o.default}" for o in options_of(entry.config_cls)) or "(none)"
        table.add_row(name, Text(options), Text(f"the {entry.extra} extra" if entry.extra else ""))
    console = wide_console()   # (a pipe gets whole lines)
    console.print(table)
    console.print("each one's options in full: pilotlab strategy show NAME; what each does: docs/strategies.md",
                  highlight=False)
    return 0


def show_strategy(args: argparse.Namespace) -> int:
    from rich.table import Table
    from rich.text import Text
    from matrix.display import console as wide_console
    from pilotlab.strategies import STRATEGIES
    entry = STRATEGIES.get(args.name)          # an unknown name: "did you mean" and the known ones
    options = options_of(entry.config_cls)
    console = wide_console()
    if not options:
        console.print(f"{args.name} takes no options", highlight=False)
        return 0
    table = Table("option", "type", "default", "what", title=args.name)
    for option in options:
        table.add_row(option.name, Text(option.type), Text(option.default), Text(option.comment))
    console.print(table)
    console.print(f"in a recipe: strategies: {{my_{args.name}: {{use: {args.name}, {options[0].name}: ...}}}}",
                  highlight=False, markup=False)
    if entry.extra:
        console.print(f"needs the {entry.extra} extra: pip install -e '.[{entry.extra}]' (without it the strategy is "
                      "not applicable)", highlight=False, markup=False)
    return 0
