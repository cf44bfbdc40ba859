"""MkDocs hook: the CLI reference page, generated from the argparse parser itself (app.cli.build_parser), so every
command, option, default and help text in the docs is the one `python -m app ... --help` prints.

A page containing the line `<!-- cli-reference -->` gets that line replaced by one section per command.
"""

import argparse
import html
import re
import sys
from pathlib import Path

MARKER = "<!-- cli-reference -->"
USAGE_WIDTH = 100  # characters per line of a usage block, as argparse wraps it


def on_config(config):
    """The parser documented is this checkout's (as mkdocstrings' `paths: [.]`), whichever `app` is installed."""
    root = str(Path(config["config_file_path"]).parent)
    sys.path[:] = [root] + [p for p in sys.path if p != root]
    return config


def on_page_markdown(markdown: str, page, config, files) -> str:
    if MARKER not in markdown:
        return markdown
    from app.cli import build_parser

    return markdown.replace(MARKER, "\n".join(_command(build_parser(), [], "")))


def _text(value: str) -> str:
    """Help text as Markdown: one line, HTML and Markdown's emphasis and table characters escaped."""
    text = html.escape(" ".join(value.split()), quote=False)
    return re.sub(r"([*_|\[\]])", r"\\\1", text)


def _subcommands(parser: argparse.ArgumentParser):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {choice.dest: choice.help for choice in action._choices_actions}
            return [(name, sub, helps.get(name) or "") for name, sub in action.choices.items()]
    return []


def _option(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    formatter = parser._get_formatter()
    if action.option_strings:
        metavar = formatter._format_args(action, action.dest.upper()) if action.nargs != 0 else ""
        name = ", ".join(f"{flag} {metavar}".strip() for flag in action.option_strings)
    else:
        name = formatter._format_args(action, action.dest)
    help_text = formatter._expand_help(action) if action.help else ""
    if action.required and action.option_strings:
        help_text += " (required)"
    if action.choices is not None and not isinstance(action, argparse._SubParsersAction):
        help_text += f" (one of: {', '.join(map(str, action.choices))})"
    shown_default = action.option_strings and action.nargs != 0 and action.default not in (None, argparse.SUPPRESS, [])
    if shown_default and "%(default)" not in (action.help or "") and "default" not in help_text:
        help_text += f" (default: {action.default})"
    return f"- `{name}`: {_text(help_text)}"


def _command(parser: argparse.ArgumentParser, path: list[str], summary: str) -> list[str]:
    subcommands = _subcommands(parser)
    lines = []
    if path:
        level = "#" * min(len(path) + 1, 4)
        lines += [f"{level} `{' '.join(path)}`", ""]
        if summary:
            lines += [_text(summary[0].upper() + summary[1:]) + ".", ""]
    if parser.description and path:
        lines += [_text(parser.description), ""]
    formatter = parser.formatter_class(prog=parser.prog, width=USAGE_WIDTH)
    formatter.add_usage(parser.usage, parser._actions, parser._mutually_exclusive_groups, prefix="")
    lines += ["```text", formatter.format_help().strip(), "```", ""]
    options = [
        a
        for a in parser._actions
        if not isinstance(a, (argparse._HelpAction, argparse._SubParsersAction)) and a.help != argparse.SUPPRESS
    ]
    lines += [_option(parser, a) for a in options]
    lines.append("")
    for name, sub, help_text in subcommands:
        lines += _command(sub, [*path, name], help_text)
    return lines
