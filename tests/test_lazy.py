"""The lazy re-exports read each submodule's ``__all__`` from its text (spa._lazy)."""

from __future__ import annotations

from pathlib import Path

import pytest

import spa
from spa._lazy import _parsed_names, declared_names

PACKAGE = Path(spa.__file__).parent


def _with_all(path: Path) -> list[Path]:
    return [p for p in sorted(path.rglob("*.py")) if "\n__all__" in p.read_text()]


@pytest.mark.parametrize("module", _with_all(PACKAGE), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_the_text_gives_what_the_parse_gives(module: Path) -> None:
    try:
        parsed = _parsed_names(module.read_text(), module)
    except ValueError:  # an __all__ built by code (a package's lazy list): never read by text
        with pytest.raises(ValueError, match="no literal __all__"):
            declared_names(module)
    else:
        assert declared_names(module) == parsed


@pytest.mark.parametrize(
    "body",
    [
        '__all__ = [\n    "a",  # the first ]\n    "b",\n]\n',  # a bracket in a comment
        '__all__ = (\n    "a",\n    "b"\n)\n',
    ],
)
def test_lists_the_text_cannot_read_are_parsed(tmp_path: Path, body: str) -> None:
    module = tmp_path / "m.py"
    module.write_text('"""Doc."""\n\n' + body)
    assert declared_names(module) == ["a", "b"]


def test_a_module_without_a_literal_list_is_an_error(tmp_path: Path) -> None:
    module = tmp_path / "m.py"
    module.write_text("__all__ = sorted(['a'])\n")
    with pytest.raises(ValueError, match="no literal __all__"):
        declared_names(module)
    module.write_text('__all__ = ["a"] + ["b"]\n')  # not a plain list: never half of it
    with pytest.raises(ValueError, match="no literal __all__"):
        declared_names(module)
