"""The mission's plan: the vista points that cover every component of the mock-up (seed §4).

:func:`plan_vistas` gives the plan ``MissionSettings.plan`` names: ``"cad"`` the plan generated from any
mock-up's CAD model (:func:`rsi.mission.plan_cad.generate_plan`, no layout named), ``"hand"`` the **hand
plan**, and ``"auto"`` (the default) the hand plan on the truss, where the mission's figures are
measured on it, and the CAD plan on any other layout. The hand plan is kept as a named comparison: ten
points placed by hand on the ``truss`` layout only. Its names and offsets below are that layout's: the
mock-up's own vistas cover its components, the solar panel's dark cells need closer views (see
:func:`panel_vistas`), and the electrical ORU's inside is seen with its door open (seed §4 A).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rsi import _validate as v
from rsi.errors import InputError
from rsi.mission.records import PlanPoint
from rsi.mission.settings import MissionSettings

if TYPE_CHECKING:
    from rsi.sim.mockup import Vista
    from rsi.sim.world import World

# The hand plan on the truss layout only: the panel's four quarters (rows across the truss) and its centre,
# offsets from its vista's target
_PANEL_OFFSETS_M = {
    "C_panel_west_front": (-0.125, -0.095),
    "C_panel_west_back": (-0.125, 0.095),
    "C_panel_east_front": (0.125, -0.095),
    "C_panel_east_back": (0.125, 0.095),
    "C_panel_centre": (0.0, 0.0),
}


def panel_vistas(standoff_m: float, centre: tuple[float, float, float] | None = None) -> tuple[Vista, ...]:
    """Five close views of the solar panel at `standoff_m` that the mock-up does not list (seed §4 C).

    At the 0.5 m standoff a pixel is 0.66 mm on the dark cells: a millimetre impact covers two pixels and
    the cells' 0.8 mm texels alias from visit to visit. At 0.35 m a pixel is 0.46 mm; four views, the
    image's rows across the truss, cover the panel and its corner screws, and a fifth looks straight at
    the component's site, where a replacement's dent would be: in the corners of the other four a crater is
    seen obliquely and its shading hides the spots in it.
    """
    from rsi.sim.mockup import truss_mockup, vista

    standoff_m = v.positive(standoff_m, "standoff_m")
    centre = truss_mockup().vistas["C_panel"].target_m if centre is None else v.vector3(centre, "centre")
    return tuple(
        vista(name, (centre[0] + dx, centre[1] + dy, centre[2]), (0.0, 0.0, 1.0), (0.0, 1.0, 0.0), standoff_m)
        for name, (dx, dy) in _PANEL_OFFSETS_M.items()
    )


def plan_points(settings: MissionSettings) -> tuple[PlanPoint, ...]:
    """The plan's vista points in visiting order: the electrical ORU closed, open and its Kapton, the
    tank ORU, the five panel views, the tubing."""
    settings = v.instance_of(settings, "settings", MissionSettings, none_allowed=False)
    panel = [PlanPoint(name, name) for name in _PANEL_OFFSETS_M]
    return (
        PlanPoint("A_door", "A_door"),
        PlanPoint("A_door_open", "A_door", settings.door_open_rad),
        PlanPoint("A_kapton", "A_kapton"),
        PlanPoint("B_tank", "B_tank"),
        *panel,
        PlanPoint("D_tubing", "D_tubing"),
    )


PLAN: tuple[PlanPoint, ...] = plan_points(MissionSettings())


def plan_vistas(world: World, settings: MissionSettings | None = None) -> tuple[PlanPoint, ...]:
    """Add the plan's vistas to `world` (once) and return the plan (``settings.plan``: see the module notes).

    Raises InputError for a world that is not a World, settings that are not MissionSettings, or the hand
    plan asked of a world whose mock-up lacks its vistas (the hand plan is the truss layout's).
    """
    from rsi.sim.world import World

    settings = v.instance_or_default(settings, "settings", MissionSettings)
    v.instance_of(world, "world", World, none_allowed=False)
    if settings.plan == "cad" or (settings.plan == "auto" and world.mockup.layout != "truss"):
        from rsi.mission.plan_cad import add_plan_vistas, generate_plan

        return add_plan_vistas(world, generate_plan(world, settings))
    return hand_plan_vistas(world, settings)


def hand_plan_vistas(world: World, settings: MissionSettings) -> tuple[PlanPoint, ...]:
    """Add the hand plan's panel vistas to `world` (once) and return the hand plan (truss layout only)."""
    from rsi.sim.world import World

    v.instance_of(world, "world", World, none_allowed=False)
    settings = v.instance_of(settings, "settings", MissionSettings, none_allowed=False)
    if world.mockup.layout != "truss":
        raise InputError(
            f"the hand plan is the truss layout's and this world's mock-up is {world.mockup.layout!r}; "
            "use MissionSettings(plan='cad') (or 'auto') for a plan from this mock-up's CAD model."
        )
    centre = world.vista("C_panel").target_m
    for point in panel_vistas(settings.panel_standoff_m, centre):
        if point.name not in world.vistas:
            world.add_vista(point)
    return plan_points(settings)


__all__ = ["PLAN", "hand_plan_vistas", "panel_vistas", "plan_points", "plan_vistas"]
