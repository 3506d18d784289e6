"""What every command shares: exit codes, the campaign and calibration a command reads, its
progress, and how a summary names the files written."""
from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

from calibration.data.campaign import open_campaign
from calibration.data.errors import InputError
from calibration.data.outputs import read_result, write_result

EXIT_OK, EXIT_INTERNAL, EXIT_INPUT = 0, 1, 2


def names(*paths) -> str:
    """'a, b and c' of the files written (None: not written)."""
    written = [str(p) for p in paths if p is not None]
    return written[0] if len(written) == 1 else f"{', '.join(written[:-1])} and {written[-1]}"


def progress_for(args):
    """Messages and counted bars on stderr (calibration/progress.py); None with --quiet."""
    if getattr(args, "quiet", False):
        return None
    from calibration.progress import Progress

    return Progress()


def campaign_of(args):
    """The command's campaign, its run files held inside its folder unless --allow-outside."""
    return open_campaign(args.campaign, allow_outside=args.allow_outside)


@contextmanager
def about_calibration(path):
    """Errors raised while a calibration file's content is used name that file: an
    InputError keyed by one of the file's keys (not a command-line option) gets its path."""
    try:
        yield
    except InputError as e:
        if e.key is not None and not e.key.startswith("-"):
            raise e.located(path) from None
        raise


def read_calibration(path) -> dict:
    """A calibration file (railcal calibrate --out) with a parameters table, or exit 2."""
    path = Path(path)
    calibration = read_result(path, ("calibration", "diagnosis"))
    if "parameters" not in calibration:
        raise InputError("not a calibration result: no 'parameters'", path=path, key="parameters")
    params = calibration["parameters"]
    if not isinstance(params, dict):
        raise InputError(f"'parameters' must map names to values, got {type(params).__name__}", path=path,
                         key="parameters")
    return calibration


def track_for_crosscheck(args):
    """(distance, level) [m] of --track, or a synthetic track (German low-disturbance spectrum,
    3-70 m) long enough for --speed x --duration."""
    from calibration.data.campaign import read_track_file

    if args.track:
        rec = read_track_file(Path(args.track))
        return rec.distance, rec.level
    from fmu_src.reference import smooth_profile

    s, z, _ = smooth_profile(args.speed * args.duration + 60.0, seed=3)
    return s, z


def read_identification(path, campaign, parse):
    """``parse(data)`` of an identification file (railcal identify --out) made from
    ``campaign`` as it is now, or exit 2 naming the file: its kind must be the campaign's
    and its recorded fingerprint the campaign's files'
    (:meth:`~calibration.data.campaign.Campaign.fingerprint`)."""
    path = Path(path)
    data = read_result(path, ("identification",))
    if data.get("kind") != campaign.meta.kind:
        raise InputError(f"an identification of a {data.get('kind')!r} campaign, not of this {campaign.meta.kind} "
                         "one", path=path, key="kind")
    recorded = data.get("campaign_sha256")
    if recorded is None:
        raise InputError("records no campaign fingerprint (made by an older railcal): run railcal identify again",
                         path=path, key="campaign_sha256")
    if recorded != campaign.fingerprint():
        raise InputError(f"made from another campaign than {campaign.root}, or from this one before its files "
                         "changed: run railcal identify on it again", path=path, key="campaign_sha256")
    with about_calibration(path):
        return parse(data)


def write_calibration(out: dict, path) -> list[Path]:
    """Write the calibration file ``out`` at ``path`` with its figures beside it: the search's
    convergence (.png, :mod:`calibration.convergence_plots`) and, when ``out`` has a MAC matrix,
    the matrix (``_mac.png``, listed under ``plots``). Returns the figures' paths."""
    from calibration.convergence_plots import plot_convergence

    png = plot_convergence(out, Path(path).with_suffix(".png"))
    figures = [] if png is None else [png]
    matrix = out.get("mac_matrix")
    if matrix:
        from calibration.identification.plots import plot_mac

        mac = plot_mac(matrix["values"], matrix["identified"], matrix["model"], mac_figure(path),
                       y_name="identified mode", x_name="calibrated model's mode")
        figures.append(mac)
        out = {**out, "plots": [*(out.get("plots") or []), mac.name]}
    write_result(path, {**out, "plot": None if png is None else str(png)}, "calibration")
    return figures


MAC_FIGURE = "_mac"  # the suffix of a calibration's MAC matrix figure


def mac_figure(path) -> Path:
    """The MAC matrix figure of the calibration file at ``path``."""
    path = Path(path)
    return path.with_name(path.stem + MAC_FIGURE + ".png")
