"""The reference pages' generated regions are what the code gives now."""

import pytest
from support.docs_reference import PAGES, REPO, regenerate, with_region


def test_every_generated_region_matches_the_code():
    stale = regenerate(write=False)
    assert not stale, (
        f"{', '.join(stale)} differ from the code: run python tests/support/docs_reference.py"
    )


@pytest.mark.parametrize("page", sorted(PAGES))
def test_a_changed_region_is_caught(page):
    """The comparison sees an edit inside the region (the check can fail)."""
    text = (REPO / page).read_text(encoding="utf-8")
    assert with_region(text, PAGES[page]() + "\nan edit\n", page) != text


def test_the_cli_page_lists_every_command():
    """Every command of the tree, nested groups included, has its section."""
    from labrig.cli import COMMANDS

    text = (REPO / "docs/reference/cli.md").read_text(encoding="utf-8")
    for name in COMMANDS:
        assert f"### `labrig {name}`" in text
    for nested in ("labrig model scan", "labrig pump status", "labrig library add"):
        assert f"### `{nested}`" in text


def test_the_schema_pages_list_every_field_of_every_model():
    """An independent walk over the pydantic models: each field appears as a key."""
    from pydantic import BaseModel

    from labrig.config import protocol, rig_file

    for module, page in ((protocol, "protocol.md"), (rig_file, "rig-file.md")):
        text = (REPO / "docs/reference" / page).read_text(encoding="utf-8")
        models = [
            value
            for value in vars(module).values()
            if isinstance(value, type) and issubclass(value, BaseModel) and value.model_fields
        ]
        assert models
        for model in models:
            for field in model.model_fields:
                as_row, as_step_kind = f"| `{field}` |", f"`{field}` (see "
                assert as_row in text or as_step_kind in text, f"{page}: {model.__name__}.{field}"


def test_a_region_without_markers_is_named():
    with pytest.raises(ValueError, match=r"docs/x\.md: no region"):
        with_region("no markers here", "generated", "docs/x.md")


def test_every_public_name_of_the_python_api_is_documented():
    from support.docs_reference import undocumented

    assert undocumented() == []


def test_the_python_api_page_lists_every_public_name_and_nothing_private():
    import labrig

    text = (REPO / "docs/reference/python-api.md").read_text(encoding="utf-8")
    public = [name for name in labrig.__all__ if not name.startswith("__")]
    assert {"open_run", "open_runs", "segment", "actuator", "open_scan"} <= set(public)
    for name in public:
        assert f"### `labrig.{name}" in text
    assert not any(name.startswith("_") for name in public)
    assert "labrig.api." not in text.split("<!-- generated")[1]
    with pytest.raises(AttributeError, match="no attribute 'api_internals'"):
        labrig.api_internals  # noqa: B018
