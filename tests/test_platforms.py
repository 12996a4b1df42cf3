"""Issue 53: one platform registry (``robots/dvrk/platforms.py``), carts as classes (``studies/port_place/carts.py``).

A platform added in a test touches the registry only: a Classic cart raised 150 mm on a base (its world frame
0.15 m above the floor) is one ``Platform`` entry; configs take it by name, and its rows are checked against
physics apart from the code: only the patient's height in the cart's frame matters, so the raised cart under a
table 150 mm higher gives the Classic's rows in every column, and under the same table it does not."""
import dataclasses

import numpy as np
import pytest

from surgopt.robots.dvrk import platforms as P
from surgopt.studies.port_place import carts as CT
from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import study as S

SMALL = {"patient": {"port_region": {"site_spacing_mm": 72.0}}, "target": {"spacing_mm": 20.0}, "cart": {"model": "none"}}


def test_every_list_of_carts_is_the_registrys():
    assert P.CART_MODELS == ("none", *P.PLATFORMS, "auto") == P.cart_models()
    assert C.Cart.model_json_schema()["properties"]["model"]["enum"] == list(P.CART_MODELS)
    for name, platform in P.PLATFORMS.items():
        assert platform.name == name and set(platform.sujs) == set(P.ROLES)
        assert all(s.arm == role for role, s in platform.sujs.items())
        cart = CT.cart_named(name)
        assert isinstance(cart, CT.FAMILIES[platform.suj_family]) and cart.platform is platform
        assert cart.roll_is_free == platform.roll_is_free
    assert CT.cart_named("none") is CT.NO_CART and not CT.NO_CART.docks
    assert [P.role_of(P.column_prefix(r)) for r in P.ROLES] == list(P.ROLES)
    with pytest.raises(KeyError, match="names no arm role"):
        P.role_of("psm4")


def test_a_platform_added_to_the_registry_alone_docks(monkeypatch):
    classic = P.PLATFORMS["classic"]
    raised = dataclasses.replace(classic, name="raised", title="raised Classic", world_above_floor_m=0.15,
                                 world_above_floor_source="a test's: the Classic on a 150 mm base")
    monkeypatch.setitem(P.PLATFORMS, "raised", raised)

    def rows(model, table_mm):
        cfg = C.PortPlaceConfig.model_validate({**SMALL, "cart": {"model": model, "table_height_mm": table_mm}})
        assert cfg.cart.model == model
        return S.compute_task(cfg, S.n_total(cfg), 0)

    base = rows("classic", 800.0)
    assert (base["cart_pose"] >= 0).any()  # the premise: layouts dock
    same = rows("raised", 950.0)
    for c, v in base.items():
        np.testing.assert_allclose(np.asarray(same[c], float), np.asarray(v, float), rtol=0, atol=1e-9, err_msg=c)
    lower = rows("raised", 800.0)  # the same table: the arms' mounts 150 mm higher over the patient
    assert any(not np.allclose(np.asarray(lower[c], float), np.asarray(base[c], float), equal_nan=True)
               for c in base if c.endswith("_suj_column_mm"))
    with pytest.raises(ValueError, match="Input should be 'none', 'classic', 'si', 'raised' or 'auto'"):
        C.PortPlaceConfig.model_validate({"cart": {"model": "xi"}})
