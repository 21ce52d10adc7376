"""Write the CLI reference page from ``spa.cli``'s argparse parser.

One section per command: its one-line summary, its description, and its ``--help`` text as
the parser prints it, so the page cannot drift from the command.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path


def _subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, str, argparse.ArgumentParser]]:
    """``(name, one-line help, parser)`` of every command, in the parser's order."""
    for action in parser._actions:  # argparse has no public accessor for subparsers
        if isinstance(action, argparse._SubParsersAction):
            # argparse escapes "%" in help as "%%" (it formats help with %); the page must not
            helps = {a.dest: (a.help or "").replace("%%", "%") for a in action._choices_actions}
            return [(name, helps.get(name, ""), sub) for name, sub in action.choices.items()]
    return []


def cli_page() -> str:
    """The Markdown text of the CLI reference."""
    from spa.cli import _parser

    os.environ["COLUMNS"] = "90"  # argparse wraps at the terminal's width: fix it
    parser = _parser()
    lines = [
        "# The `spa` command",
        "",
        "Generated from the command's own parser (`spa/cli.py`). `spa --help` lists the",
        "commands, `spa COMMAND --help` gives one command's arguments and `spa --version`",
        "prints the installed version. The pipeline itself runs with `snakemake",
        "reproduce-all` ({doc}`../getting-started/first-run`).",
        "",
        "| command | what it does |",
        "|---|---|",
    ]
    commands = _subcommands(parser)
    lines += [f"| [`spa {name}`](#spa-{name}) | {summary} |" for name, summary, _ in commands]
    lines += ["", "```text", parser.format_help().rstrip(), "```", ""]
    for name, summary, sub in commands:
        lines += [
            f"(spa-{name})=",
            f"## `spa {name}`",
            "",
            f"{summary[:1].upper()}{summary[1:]}.",
            "",
            "```text",
            sub.format_help().rstrip(),
            "```",
            "",
        ]
    return "\n".join(lines)


def write_cli_page(path: Path) -> Path:
    """Write :func:`cli_page` to ``path`` unless it already holds that text."""
    text = cli_page()
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.is_file() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")
    return path
