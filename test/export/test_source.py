"""A record field's source: its words and its kind apart (no kind read back from the words)."""

from __future__ import annotations

import copy
import json
import pickle

from phid_ros.export.source import Origin, Source


def test_a_source_prints_its_words_and_is_judged_by_its_origin() -> None:
    widened = Source("default: widened to what the recordings reached (a limit never reached)", Origin.WIDENED)
    assert widened.is_default and widened.origin is Origin.WIDENED
    # words that begin like a default's are not one: the kind is the origin's
    assert not Source("default-free fit, identified", Origin.IDENTIFIED).is_default
    effect = Source.of_effect("subtransient_dynamics", "t_q0pp")
    assert effect == "diagnosis: subtransient_dynamics t_q0pp" and effect.effect == ("subtransient_dynamics", "t_q0pp")
    flagged = effect.flag()
    assert flagged == "diagnosis: subtransient_dynamics t_q0pp NOT IDENTIFIED" and flagged.flagged
    assert flagged.flag() == flagged and flagged.effect == effect.effect  # flagged once, the effect kept
    assert json.dumps({"Tq20": flagged}) == '{"Tq20": "diagnosis: subtransient_dynamics t_q0pp NOT IDENTIFIED"}'
    back = pickle.loads(pickle.dumps(flagged))
    assert back == flagged and back.origin is Origin.DIAGNOSIS and back.effect == effect.effect and back.flagged
    assert copy.deepcopy(widened).origin is Origin.WIDENED
