from collections import Counter

from phid_ros.sim.scenarios import paper_catalogue


def test_catalogue_matches_section_4():
    cat = paper_catalogue()
    ident = [s for s in cat if s.role == "identify"]
    kinds = Counter((s.kind, s.generator_damping) for s in ident)
    assert kinds == {("torque_step", False): 2, ("torque_step", True): 5, ("voltage_step", True): 4, ("fault", True): 4}
    assert sorted(s.magnitude for s in ident if s.kind == "torque_step" and s.generator_damping) == [
        -0.10,
        -0.05,
        0.05,
        0.10,
        0.15,
    ]
    assert sorted(s.magnitude for s in ident if not s.generator_damping) == [-0.10, 0.10]
    assert sorted(s.magnitude for s in ident if s.kind == "fault") == [0.05, 0.10, 0.15, 0.20]
    assert all(s.t_event == 1.0 and s.duration == 30.0 for s in ident)
    val = [s for s in cat if s.role == "validate"]
    assert [(s.kind, s.magnitude) for s in val] == [("torque_step", 0.16), ("voltage_step", 0.85), ("fault", 0.150)]
    assert len({s.name for s in cat}) == len(cat)
