"""Every import declared; an optional one missing is one line naming its extra, never a traceback."""

import ast
import importlib.metadata as md
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from phid_ros import cluster
from phid_ros.extras import EXTRAS, IN_CORE, MissingExtraError, require

ROOT = Path(__file__).resolve().parents[1]
ROS_ONLY = {"rclpy", "launch", "launch_ros", "launch_testing", "launch_testing_ros", "ament_index_python"}
ROS_ONLY |= {
    "std_msgs",
    "std_srvs",
    "diagnostic_msgs",
    "builtin_interfaces",
    "phid_msgs",
    "rosgraph_msgs",
    "rcl_interfaces",
}


def _imported_modules() -> set[str]:
    found: set[str] = set()
    for path in (ROOT / "phid_ros").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                found |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                found.add(node.module.split(".")[0])
    return found - set(sys.stdlib_module_names) - {"phid_ros", "__future__"} - ROS_ONLY


def _declared() -> dict[str, set[str]]:
    """distribution name -> the extras it comes with ('' for install_requires)."""
    out: dict[str, set[str]] = {}
    for req in md.requires("phid_ros") or []:
        name = re.match(r"[A-Za-z0-9_.-]+", req).group(0).lower().replace("_", "-")
        extra = re.search(r'extra == "([^"]+)"', req)
        out.setdefault(name, set()).add(extra.group(1) if extra else "")
    return out


def test_every_third_party_import_is_a_declared_requirement():
    dists = md.packages_distributions()
    declared = _declared()
    undeclared = []
    for module in sorted(_imported_modules()):
        names = {d.lower().replace("_", "-") for d in dists.get(module, [module])}
        if not names & declared.keys():
            undeclared.append(f"{module} ({', '.join(sorted(names))})")
    assert not undeclared, f"imported but not in setup.py: {undeclared}"


def test_the_optional_modules_are_extras_and_not_hard_requirements():
    """Each extra's modules come with it; only the extras the core install brings too (numba and
    comtrade: a newcomer's first diagnosis and first COMTRADE file) are also hard requirements."""
    declared = _declared()
    for extra, modules in EXTRAS.items():
        for module in modules:
            assert extra in declared[module], (module, declared[module])
            assert ("" in declared[module]) == (extra in IN_CORE), (module, declared[module])
    for extra in ("jit", "fleet", "field"):
        assert set(EXTRAS[extra]) <= {n for n, e in declared.items() if "test" in e and "all" in e}


def test_a_missing_extra_is_one_line_naming_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "comtrade", None)  # import comtrade raises ImportError
    with pytest.raises(MissingExtraError) as err:
        require("comtrade", "field", "rec.cfg: reading COMTRADE")
    msg = str(err.value)
    assert "\n" not in msg and "rec.cfg" in msg and "pip install 'phid_ros[field]'" in msg


def test_import_comtrade_without_the_field_extra_says_so(monkeypatch, tmp_path):
    from phid_ros.io.field.comtrade_dat import open_recording

    (tmp_path / "rec.cfg").write_text("STATION,DEVICE,1999\n")
    monkeypatch.setitem(sys.modules, "comtrade", None)
    with pytest.raises(MissingExtraError, match=r"\[field\]"):
        open_recording(tmp_path / "rec.cfg")


def test_jobs_run_here_without_dask(monkeypatch):
    monkeypatch.setattr(cluster, "installed", lambda extra: False)

    def started(*a, **k):
        raise AssertionError("a Dask cluster was started without the [fleet] extra")

    monkeypatch.setattr(cluster, "cluster", started)
    with cluster.Jobs(2) as jobs:
        got = jobs.map(np.add, [(1, 2), (3, 4), (5, 6)])
    assert got == [3, 7, 11]


def test_phid_fleet_without_dask_says_which_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(MissingExtraError, match=r"phid_ros\[fleet\]"):
        cluster.cluster(None, 1).__enter__()
