"""YAML documents a user writes (channel maps, fleet lists), read so that small files stay small
and a key means what it says.

- Anchors and aliases are refused: a 600-byte file of nested aliases expands to gigabytes when
  walked, and none of our documents needs them.
- Keys are the text written: YAML 1.1 reads ``0412:`` as the octal number 266, and a recording's
  settings under its file stem ``0412`` were dropped without a word.
- A key given twice in one mapping is refused: YAML keeps the second and drops the first, and a
  recording's settings written twice lost the first entry (its kind, its regulator) silently.
- A document larger than :data:`MAX_YAML_BYTES` is refused before it is parsed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from phid_ros.errors import PhidError

MAX_YAML_BYTES = 1 << 20  # a channel map is a few hundred bytes, a fleet list of 10 000 units ~1 MB


class YamlDocError(PhidError):
    """A YAML document that phid does not read (aliases, too large, not YAML)."""


def _loader(all_text: bool) -> type[yaml.SafeLoader]:
    class Loader(yaml.SafeLoader):
        def compose_node(self, parent: Any, index: Any) -> Any:
            if self.check_event(yaml.AliasEvent):
                event = self.peek_event()
                mark = event.start_mark
                raise YamlDocError(
                    f"line {mark.line + 1}: the alias *{event.anchor} (anchors and aliases are not read here: "
                    "write the values out)"
                )
            return super().compose_node(parent, index)

        def construct_mapping(self, node: Any, deep: bool = False) -> Any:
            seen: dict[str, int] = {}
            for key, _ in node.value:
                if isinstance(key, yaml.ScalarNode):
                    key.tag = "tag:yaml.org,2002:str"  # the key as written: 0412 is a name, not 266
                    line = key.start_mark.line + 1
                    if key.value in seen:
                        raise YamlDocError(
                            f"line {line}: the key {key.value!r} is given twice (first on line {seen[key.value]}): "
                            "one entry per key, or the first is lost"
                        )
                    seen[key.value] = line
            return super().construct_mapping(node, deep=deep)

    if all_text:  # every scalar as written (names and paths: a recording called 0412 is not 266)
        Loader.add_constructor("tag:yaml.org,2002:int", Loader.construct_yaml_str)
        Loader.add_constructor("tag:yaml.org,2002:float", Loader.construct_yaml_str)
        Loader.add_constructor("tag:yaml.org,2002:bool", Loader.construct_yaml_str)
    return Loader


def load_yaml_text(text: str, source: str, *, all_text: bool = False) -> Any:
    """The document in ``text`` (from ``source``, for messages); ``all_text`` keeps every scalar as
    its text. Errors are one line naming ``source``."""
    if len(text) > MAX_YAML_BYTES:
        raise YamlDocError(f"{source}: {len(text) >> 10} KB of YAML, more than the {MAX_YAML_BYTES >> 10} KB read")
    try:
        return yaml.load(text, Loader=_loader(all_text))  # noqa: S506 (a SafeLoader)
    except YamlDocError as exc:
        raise YamlDocError(f"{source}: {exc}") from None
    except yaml.YAMLError as exc:
        raise YamlDocError(f"{source}: not valid YAML ({exc})".replace("\n", " ")) from None


def load_yaml(path: str | Path, *, all_text: bool = False) -> Any:
    """The YAML document at ``path``, read with :func:`load_yaml_text`'s bounds."""
    p = Path(path)
    try:
        with p.open(encoding="utf-8") as fh:
            text = fh.read(MAX_YAML_BYTES + 1)
    except (OSError, UnicodeDecodeError) as exc:
        raise YamlDocError(f"{p}: cannot read ({exc})") from None
    return load_yaml_text(text, str(p), all_text=all_text)
