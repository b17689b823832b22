"""``robocal ur`` commands: extract, correct, defaults, verify, plot."""

from __future__ import annotations

import contextlib
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.table import Table

from ..errors import UsageError
from ._catalog import UR_MODEL_NAMES
from ._common import console, err_console, exit_code_for, print_warning, print_warnings

if TYPE_CHECKING:
    from ..workflows.ur import job as wf
    from ..workflows.ur import verify as ur_verify

app = typer.Typer(
    help="Universal Robots: calibrated kinematics for ur_description (extract, correct, defaults, verify, plot, view).",
    no_args_is_help=True,
)

RPY_HELP = (
    "Angle convention (any case): 'urdf' (correct, default) or 'upstream' (ur_calibration's Eigen angles)."
)
MODELS = ", ".join(UR_MODEL_NAMES)
DELTAS_HELP = "Calibration deltas (delta_theta/a/d/alpha)."
DEFAULTS_RPY_HELP = (
    "Angle convention (any case): 'upstream' (default) writes ur_calibration's Eigen angles, as in the "
    "checked-in default_kinematics.yaml files; 'urdf' writes URDF-convention angles."
)

_YamlOut = Annotated[Path, typer.Option("--out", help="Kinematics YAML to write.")]
_NominalModel = Annotated[str | None, typer.Option("--model", help=f"UR model for nominal DH ({MODELS}).")]
_Deltas = Annotated[Path | None, typer.Option("--deltas", help=DELTAS_HELP)]
_Rpy = Annotated[str, typer.Option("--rpy", help=RPY_HELP)]
_UrdfIn = Annotated[Path | None, typer.Option("--urdf-in", help="Expanded URDF to update.")]
_UrdfOut = Annotated[Path | None, typer.Option("--urdf-out", help="Updated URDF to write.")]


def _print_result(result: wf.CorrectionResult, replaced: bool) -> int:
    table = Table("link", "x", "y", "z", "roll", "pitch", "yaw", box=None, pad_edge=False)
    for link in result.kinematics.links:
        table.add_row(link.name, *(f"{v:.9g}" for v in (*link.xyz_m, *link.rpy_rad)))
    console.print(table)
    console.print(f"hash: {result.kinematics.hash}  (rpy convention: {result.kinematics.rpy_convention})")
    dev = result.deviation
    console.print(
        f"deviation from nominal {dev.model}: {dev.length_m * 1e3:.3f} mm ({dev.length_field}), "
        f"{dev.angle_rad * 1e3:.3f} mrad"
    )
    console.print(f"wrote {result.out_path}")
    if replaced:  # said only once the new file is in place; a failed run leaves the old one untouched
        err_console.print(
            f"note: replaced {result.out_path} (previous file kept as {result.out_path.name}.bak)"
        )
    if result.urdf_out is not None:
        console.print(f"wrote {result.urdf_out} (six joint origins updated)")
    return print_warnings(result.warnings)


@app.command("extract")
def extract(
    host: Annotated[str, typer.Option("--host", help="Controller IP or host name.")],
    out: _YamlOut,
    port: Annotated[int, typer.Option("--port", help="Primary interface port (30011 = read-only).")] = 30001,
    timeout: Annotated[float, typer.Option("--timeout", help="Seconds to wait for KinematicsInfo.")] = 10.0,
    rpy: _Rpy = "urdf",
    urdf_in: _UrdfIn = None,
    urdf_out: _UrdfOut = None,
) -> None:
    """Read the calibrated DH from a controller, correct it and write ur_description's kinematics YAML."""
    from ..workflows.ur import job as wf

    replaced = out.is_file()
    result = wf.extract(host, out, port=port, timeout_s=timeout, rpy=rpy, urdf_in=urdf_in, urdf_out=urdf_out)
    raise typer.Exit(_print_result(result, replaced))


@app.command("correct")
def correct(
    out: _YamlOut,
    dh: Annotated[Path | None, typer.Option("--dh", help="DH YAML (dh_theta, dh_a, dh_d, dh_alpha).")] = None,
    model: _NominalModel = None,
    deltas: _Deltas = None,
    rpy: _Rpy = "urdf",
    urdf_in: _UrdfIn = None,
    urdf_out: _UrdfOut = None,
) -> None:
    """Correct DH parameters offline (no robot) and write ur_description's kinematics YAML."""
    from ..workflows.ur import job as wf

    input_warnings: list[str] = []
    for path, what in ((out, "--out"), (urdf_out, "--urdf-out")):
        if path is not None:
            wf.check_out_path(path, what, {"--dh": dh, "--deltas": deltas})
    params = wf.load_dh_input(dh, model, deltas, warnings=input_warnings)
    replaced = out.is_file()
    result = wf.correct(
        params, out, rpy=rpy, urdf_in=urdf_in, urdf_out=urdf_out, warnings=tuple(input_warnings)
    )
    raise typer.Exit(_print_result(result, replaced))


@app.command("defaults")
def defaults(
    model: Annotated[str, typer.Option("--model", help=f"UR model ({MODELS}).")],
    out: _YamlOut,
    rpy: Annotated[str, typer.Option("--rpy", help=DEFAULTS_RPY_HELP)] = "upstream",
) -> None:
    """Regenerate ur_description's default_kinematics.yaml for a model from URSim's nominal DH.

    By default the angles are written in upstream mode (ur_calibration's Eigen eulerAngles), exactly as the
    checked-in default files; --rpy urdf writes URDF-convention angles instead (the same rotations for
    nominal models).
    """
    from ..workflows.ur import job as wf

    replaced = out.is_file()
    raise typer.Exit(_print_result(wf.defaults(model, out, rpy=rpy), replaced))


def print_reports(reports: list[ur_verify.VerifyReport], input_warnings: list[str] | None = None) -> int:
    """Print the verification table and warnings; return 1 when there are warnings, else 0."""
    table = Table(box=None)
    table.add_column("source", overflow="fold")
    for col in ("samples", "max Δp (m)", "max Δrot (rad)", "hash"):
        table.add_column(col)
    warnings: list[str] = list(input_warnings or ())
    for r in reports:
        hash_state = "-" if r.file_hash is None else ("match" if r.file_hash == r.dh_hash else "MISMATCH")
        kind, _, path = r.source.rpartition(" ")
        table.add_row(
            f"{kind} {Path(path).name}",
            str(r.samples),
            f"{r.max_position_error_m:.3g}",
            f"{r.max_rotation_error_rad:.3g}",
            hash_state,
        )
        warnings.extend(r.warnings)
    console.print(table)
    return print_warnings(warnings)


def _host_port(text: str, flag: str, default_port: int) -> tuple[str, int]:
    """``HOST``, ``HOST:PORT`` or ``[IPv6]:PORT`` → ``(host, port)``.

    Raises:
        UsageError: An empty host or a port that is not a number in 1..65535.
    """
    host, port_text = text, ""
    if text.startswith("["):
        host, _, rest = text[1:].partition("]")
        port_text = rest.removeprefix(":")
    elif text.count(":") == 1:
        host, _, port_text = text.partition(":")
    if not port_text:
        port = default_port
    elif port_text.isdigit() and 1 <= int(port_text) <= 65535:
        port = int(port_text)
    else:
        raise UsageError(f"{flag} {text!r}: expected HOST[:PORT] with a port in 1..65535")
    if not host.strip():
        raise UsageError(f"{flag} {text!r}: expected HOST[:PORT] with a controller address")
    return host, port


@app.command("verify")
def verify(
    file: Annotated[Path | None, typer.Argument(help="Kinematics YAML to check.")] = None,
    dh: Annotated[Path | None, typer.Option("--dh", help="DH YAML the file was made from.")] = None,
    model: _NominalModel = None,
    deltas: _Deltas = None,
    urdf: Annotated[Path | None, typer.Option("--urdf", help="Also check this expanded URDF.")] = None,
    samples: Annotated[int, typer.Option("--samples", help="Random joint vectors in [-2π, 2π].")] = 1000,
    seed: Annotated[int, typer.Option("--seed", help="Random seed.")] = 0,
    host: Annotated[
        str | None, typer.Option("--host", help="Also compare with this controller's pose.")
    ] = None,
    port: Annotated[int, typer.Option("--port", help="Primary interface port.")] = 30001,
    timeout: Annotated[float, typer.Option("--timeout", help="Seconds per controller read.")] = 10.0,
    controller_samples: Annotated[int, typer.Option("--controller-samples", help="States to compare.")] = 20,
    q: Annotated[
        str | None,
        typer.Option("--q", help="Compare at these joint positions (rad, 'q1,…,q6') instead of --samples random ones."),
    ] = None,
    rtde: Annotated[
        str | None,
        typer.Option(
            "--rtde",
            metavar="HOST[:PORT]",
            help="Also compare with this controller's actual_TCP_pose over RTDE (port 30004 unless given).",
        ),
    ] = None,
) -> None:
    """Compare the FK of the YAML (built like ur_description does) and/or a URDF with the DH FK.

    With --host, also compare the YAML's FK with the controller's own base→flange pose for live joint states
    (the DH then defaults to the controller's). With --rtde HOST[:PORT], compare the YAML's, the URDF's and the
    DH's FK (whichever are given) with the actual_TCP_pose the controller streams over RTDE at its actual_q.
    """
    import numpy as np

    from ..viewer.ur_page import parse_q
    from ..workflows.ur import job as wf
    from ..workflows.ur import verify as ur_verify

    reports: list[ur_verify.VerifyReport] = []
    input_warnings: list[str] = []
    if host is not None:
        if file is None:
            raise UsageError("--host needs the kinematics FILE to compare")
        reports.append(
            ur_verify.verify_controller(file, host, port=port, timeout_s=timeout, samples=controller_samples)
        )
    dh_given = dh is not None or model is not None or deltas is not None
    params = wf.load_dh_input(dh, model, deltas, warnings=input_warnings) if dh_given or host is rtde is None else None
    if params is not None and (rtde is None or file is not None or urdf is not None):
        q_rad = None if q is None else np.array([parse_q(q)])
        reports.extend(ur_verify.verify(file, params, urdf_path=urdf, samples=samples, seed=seed, q_rad=q_rad))
    if rtde is not None:
        rtde_host, rtde_port = _host_port(rtde, "--rtde", 30004)
        reports.extend(
            ur_verify.verify_rtde(
                ur_verify.RtdeVerifyRequest(
                    rtde_host,
                    port=rtde_port,
                    kinematics_path=file,
                    dh=params,
                    urdf_path=urdf,
                    timeout_s=timeout,
                    samples=controller_samples,
                )
            )
        )
    raise typer.Exit(print_reports(reports, input_warnings))


@app.command("plot")
def plot(
    out: Annotated[Path, typer.Option("--out", help="Figure to write (PNG, SVG, PDF).")],
    dh: Annotated[Path | None, typer.Option("--dh", help="DH YAML.")] = None,
    model: _NominalModel = None,
    deltas: Annotated[Path | None, typer.Option("--deltas", help="Calibration deltas.")] = None,
) -> None:
    """Plot the split DH model (arm links far away) next to the corrected model."""
    from ..workflows.ur import job as wf

    input_warnings: list[str] = []
    wf.check_out_path(out, "--out", {"--dh": dh, "--deltas": deltas})
    params = wf.load_dh_input(dh, model, deltas, warnings=input_warnings)
    console.print(f"wrote {wf.plot(params, out)}")
    raise typer.Exit(print_warnings(input_warnings))


@app.command("view")
def view(
    dh: Annotated[Path | None, typer.Option("--dh", help="Calibrated DH YAML (dh_theta, dh_a, dh_d, dh_alpha).")] = None,
    host: Annotated[str | None, typer.Option("--host", help="Read the calibrated DH from this controller.")] = None,
    port: Annotated[int, typer.Option("--port", help="Controller's primary interface port.")] = 30001,
    timeout: Annotated[float, typer.Option("--timeout", help="Seconds to wait for KinematicsInfo.")] = 10.0,
    model: Annotated[
        str | None, typer.Option("--model", help=f"Nominal UR model ({MODELS}); default: the closest one.")
    ] = None,
    q: Annotated[str | None, typer.Option("--q", help="Initial joint positions, rad ('q1,…,q6'); default 0.")] = None,
    samples: Annotated[int, typer.Option("--samples", help="Random joint vectors for max Δp (as ur verify).")] = 1000,
    seed: Annotated[int, typer.Option("--seed", help="Random seed (as ur verify).")] = 0,
    arrow_scale: Annotated[float, typer.Option("--arrow-scale", help="Drawn arrow length per metre of error.")] = 100.0,
    view_host: Annotated[str, typer.Option("--view-host", help="Interface the web page is served on.")] = "127.0.0.1",
    view_port: Annotated[int, typer.Option("--view-port", help="TCP port of the web page (0: any free port).")] = 8080,
    allow_origin: Annotated[
        list[str] | None,
        typer.Option("--allow-origin", metavar="ORIGIN", help="Also accept the page from this origin (repeatable)."),
    ] = None,
) -> None:
    """Show the nominal and the calibrated arm side by side in the browser, with tool0's position error.

    The calibrated DH comes from --dh FILE or from a controller (--host). Joint positions are set with --q and
    the page's sliders; the page shows Δp at q and max Δp over --samples random joint vectors, the numbers
    `robocal ur verify` prints for the YAML `robocal ur correct` writes from the same DH. Serves until Ctrl-C.
    """
    from ..viewer import ur_page
    from ..workflows.ur import job as wf

    if (dh is None) == (host is None):
        raise UsageError("give either --dh FILE or --host HOST")
    q_rad = ur_page.parse_q(q)
    warnings: list[str] = []
    if dh is not None:
        params = wf.load_dh_input(dh, None, None, warnings=warnings)
        source = str(dh)
    else:
        assert host is not None
        params, ctrl_warnings = wf.read_controller_dh(host, port=port, timeout_s=timeout)
        warnings.extend(ctrl_warnings)
        source = f"controller {host}:{port}"
    page = ur_page.UrViewPage(
        ur_page.UrViewModel(params, model),
        source=source,
        q_rad=q_rad,
        samples=samples,
        seed=seed,
        arrow_scale=arrow_scale,
        host=view_host,
        port=view_port,
        allowed_origins=tuple(allow_origin or ()),
    ).start()
    try:
        c = page.current
        console.print(f"robocal ur view: {page.url}  (Ctrl-C to stop)")
        console.print(
            f"{page.view.model}: Δp at q = {ur_page.format_error_m(c.error_norm_m)} m; "
            f"max Δp over {samples} samples = {ur_page.format_error_m(page.verify_m)} m"
        )
        for w in warnings:
            print_warning(w)
        with contextlib.suppress(KeyboardInterrupt):
            while page.server is not None:
                time.sleep(0.5)
    finally:
        page.stop()
    raise typer.Exit(exit_code_for(warnings))


__all__ = ["app", "print_reports"]
