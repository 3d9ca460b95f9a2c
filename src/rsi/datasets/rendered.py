"""A rendered vista written as a labelled sample: the frame, its light and depth maps, the flaw mask and the
truth (seed §4 anomalies), for users who train or test on the simulator's pictures (`rsi sim render`).

The simulator renders; writing files is this module's job (the simulator never writes images itself).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rsi import _validate as v
from rsi._files import writable_folder
from rsi.errors import InputError
from rsi.sim.render import STATES
from rsi.sim.world import DEFAULT_SIZE

if TYPE_CHECKING:
    from rsi.sim.world import World


def render_vista_to_folder(
    world: World,
    vista: str,
    out_dir: str | Path,
    *,
    size: tuple[int, int] = DEFAULT_SIZE,
    state: str = "inspection",
) -> dict[str, Path]:
    """Visit `vista` and write the frame (PNG), ambient/strobe exposures (float TIFF), depth (float TIFF),
    the flaw mask (PNG) and the truth (JSON) into `out_dir`, all or nothing.

    Every file is first written into a hidden staging folder inside `out_dir` and moved into place only
    when all were written; on a failure the staging folder, and any folder this call created, is removed.

    Returns
    -------
    dict of str to Path
        ``frame``, ``ambient``, ``strobe``, ``depth``, ``mask``, ``truth``.

    Raises
    ------
    InputError
        Naming the argument: an unknown vista or state, a bad size, or an `out_dir` that is a file, lies
        under a file, is not writable, or holds a folder where an output file must go.
    """
    from rsi._files import atomic_write_bytes
    from rsi.imaging.io import write_image
    from rsi.sim.world import World

    v.instance_of(world, "world", World, none_allowed=False)
    world.vista(vista)
    v.choice(state, "state", STATES)
    folder, created = writable_folder(out_dir, "out_dir")
    stem = f"{vista}_{state}"
    paths = {
        "frame": folder / f"{stem}_frame.png",
        "ambient": folder / f"{stem}_ambient_lux.tif",
        "strobe": folder / f"{stem}_strobe_lux_s.tif",
        "depth": folder / f"{stem}_depth_m.tif",
        "mask": folder / f"{stem}_flaw_mask.png",
        "truth": folder / f"{stem}_truth.json",
    }
    for path in paths.values():
        if path.is_dir():
            raise InputError(
                f"out_dir={str(folder)!r} holds a folder {path.name!r} where an output file must go; nothing "
                "was written. Move that folder or choose another out_dir."
            )
    view = world.render(vista, size=size, state=state)
    assert view.depth_m is not None  # rendered with truth
    visible = {
        str(k): [int(n) for n in np.argwhere(mask).mean(axis=0)[::-1]] for k, mask in view.flaw_masks.items()
    }
    truth = {
        "seed": world.seed,
        "vista": vista,
        "state": state,
        "lit_field": view.frame.lit_field,
        "exposure_s": view.frame.exposure_s,
        "pose_error_px": list(view.pose_error_px),
        "camera_position_m": view.pose.position_m.tolist(),
        "camera_rotation": view.pose.rotation.tolist(),
        "fovy_rad": view.pose.fovy_rad,
        "visible_anomaly_centres_xy": visible,
        "anomalies": world.anomalies.to_dict(),
    }
    images = {
        "frame": view.frame.raw,
        "ambient": view.ambient_lux,
        "strobe": view.strobe_lux_s,
        "depth": view.depth_m,
        "mask": (view.flaw_mask * np.uint8(255)).astype(np.uint8),
    }
    staging: Path | None = None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(dir=folder, prefix=f".{stem}."))
        for key, image in images.items():
            write_image(staging / paths[key].name, image)
        atomic_write_bytes(staging / paths["truth"].name, json.dumps(truth, indent=2).encode("utf-8"))
        for path in paths.values():
            os.replace(staging / path.name, path)
    except (OSError, InputError) as error:
        if created is not None:
            shutil.rmtree(created, ignore_errors=True)
        reason = error.strerror if isinstance(error, OSError) and error.strerror else str(error)
        raise InputError(
            f"out_dir={str(folder)!r} cannot be written ({reason}); nothing was written. "
            "Choose a folder you can write to, on a disk with room."
        ) from error
    finally:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)
    return paths
