"""Users' YAML (channel maps, fleet lists): small files stay small, keys mean what they say."""

from __future__ import annotations

import pytest

from phid_ros.io.field.channel_map import ChannelMapError, load_channel_map
from phid_ros.io.files.yaml_doc import MAX_YAML_BYTES, YamlDocError, load_yaml, load_yaml_text

# nine levels of nine aliases: 600 bytes that expand to 9^9 strings when walked
BOMB = "a: &a ['lol','lol','lol','lol','lol','lol','lol','lol','lol']\n" + "".join(
    f"{c}: &{c} [{', '.join([f'*{p}'] * 9)}]\n" for p, c in zip("abcdefgh", "bcdefghi")
)

MAP = """
machine: {mva: 30, kv: 10.5, f_nominal_hz: 50}
time: time
channels:
  v_t: {name: UG, unit: pu}
  p_e: {name: P, unit: pu}
  q_e: {name: Q, unit: pu}
scenarios:
  0412: {kind: voltage_step}
  true: {kind: field_step}
"""


def test_an_alias_bomb_is_refused_before_it_expands(tmp_path) -> None:
    assert len(BOMB) < 800
    with pytest.raises(YamlDocError, match=r"line 2: the alias \*a \(anchors and aliases are not read here"):
        load_yaml_text(BOMB, "bomb.yaml")
    path = tmp_path / "map.yaml"
    path.write_text(MAP + BOMB.replace("a:", "x:", 1))
    with pytest.raises(ChannelMapError, match=r"map\.yaml: line \d+: the alias \*a"):
        load_channel_map(path)


def test_keys_are_the_text_written_so_a_files_settings_are_not_dropped(tmp_path) -> None:
    """YAML 1.1 read ``0412:`` as the octal 266, and the settings of recording 0412 were dropped."""
    path = tmp_path / "map.yaml"
    path.write_text(MAP)
    cmap = load_channel_map(path)
    assert cmap.scenarios["0412"] == {"kind": "voltage_step"} and "true" in cmap.scenarios
    assert cmap.mva == 30  # values keep their types
    assert load_yaml_text("u: [0412, 1e3, yes]", "list.yaml", all_text=True) == {"u": ["0412", "1e3", "yes"]}


def test_a_document_beyond_the_bound_is_refused_unread(tmp_path) -> None:
    path = tmp_path / "big.yaml"
    path.write_text("# " + "x" * MAX_YAML_BYTES + "\n")
    with pytest.raises(YamlDocError, match=r"big\.yaml: 1024 KB of YAML, more than the 1024 KB read"):
        load_yaml(path)


def test_a_fleet_list_with_an_alias_bomb_or_a_numeric_unit_name(tmp_path) -> None:
    from phid_ros.fleet.inventory import InventoryError, discover

    listed = tmp_path / "fleet.yaml"
    listed.write_text(BOMB)
    with pytest.raises(InventoryError, match=r"fleet\.yaml: line 2: the alias \*a"):
        discover(listed)
    (tmp_path / "0412.mcap").write_bytes(b"\x89MCAP0\r\n")
    listed.write_text("0412: [0412.mcap]\n")
    items, _ = discover(listed)
    assert [i.unit for i in items] == ["0412"]
