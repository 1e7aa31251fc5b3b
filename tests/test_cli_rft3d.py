"""The `terradyn rft3d` command, as a user runs it: outputs and bad input (exit 2, one line)."""
import numpy as np
import pytest

from terradyn import io
from terradyn.cli import main

FAST = ["--n-angles", "19"]


def test_rft3d_netcdf_figure_and_csv(tmp_path, capsys):
    out = tmp_path / "c.nc"
    png = tmp_path / "c.png"
    assert main(["rft3d", "--body", "c", *FAST, "--medium", "poppy LP", "--out", str(out),
                 "--plot", str(png)]) == 0
    ds = io.read(out)
    assert {"Fx", "Fy", "Fz", "Tx", "Ty", "Tz"} <= set(ds.data_vars) and ds.time.size == 19
    assert ds.Fz.attrs["units"] == "N" and ds.Tx.attrs["units"] == "N m"
    assert ds.attrs["model"] == "rft3d-agarwal" and '"poppy LP"' in ds.attrs["input"]
    assert float(ds.Fz.max()) > 1 and png.stat().st_size > 20_000
    el = tmp_path / "el.nc"
    assert main(["rft3d", "--body", "flat", *FAST, "--elements-out", str(el), "-o", str(tmp_path / "f.nc")]) == 0
    import xarray as xr

    with xr.open_dataset(el, engine="h5netcdf") as e:
        tot = (e.traction_z * e.area).sum("element").values
        assert e.sizes["element"] > 1000 and e.traction_z.attrs["units"] == "N/m^2"
    np.testing.assert_allclose(tot, io.read(tmp_path / "f.nc").Fz.values, rtol=1e-9, atol=1e-12)
    assert main(["rft3d", "--body", "flat", *FAST, "--model", "treers", "--alpha", "table",
                 "--dynamic"]) == 0
    head = capsys.readouterr().out.splitlines()[0]
    assert head == "time_s,Fx_N,Fy_N,Fz_N,Tx_N_m,Ty_N_m,Tz_N_m,angle_deg"


def test_rft3d_mesh_file_and_motion_file(tmp_path, capsys):
    import trimesh

    stl = tmp_path / "box.stl"
    trimesh.creation.box(extents=(40.0, 20.0, 10.0)).export(stl)  # mm
    mot = tmp_path / "m.csv"
    t = np.linspace(0, 1, 11)
    mot.write_text("time_s,x_cm,y_cm,z_cm,qw,qx,qy,qz\n" + "\n".join(
        f"{a},{2 * a},0,{-1 - a},1,0,0,0" for a in t) + "\n")
    assert main(["rft3d", "--mesh", str(stl), "--max-edge-cm", "1", "--motion", str(mot),
                 "-o", str(tmp_path / "o.csv")]) == 0
    ds = io.read(tmp_path / "o.csv")
    assert ds.time.size == 11 and float(ds.Fx.iloc[-1] if hasattr(ds.Fx, "iloc") else ds.Fx[-1]) < 0


@pytest.mark.parametrize("args, field", [
    (["--motion", "{wrongcols}"], "motion"),
    (["--motion", "{badquat}"], "quaternion"),
    (["--mesh", "{empty}"], "mesh"),
    (["--mesh", "{nanmesh}"], "not finite"),
    (["--mesh", "{openmesh}"], "not closed"),
    (["--quat", "1,0.2,0,0"], "unit quaternion"),
    (["--quat", "1,0,0"], "quat"),
    (["--medium", "sand"], "medium"),
    (["--lambda", "2"], "lambda"),
    (["--model", "treers", "--xi-from", "friction"], "xi-from"),
    (["--out", "x.txt"], "out"),
])
def test_rft3d_bad_input_one_line_exit_2(tmp_path, capsys, args, field):
    import trimesh

    (tmp_path / "w.csv").write_text("time_s,x_cm,y_cm,z_cm,qw,qx,qy\n0,0,0,0,1,0,0\n1,0,0,0,1,0,0\n")
    (tmp_path / "q.csv").write_text("time_s,x_cm,y_cm,z_cm,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n1,0,0,0,2,0,0,0\n")
    (tmp_path / "e.obj").write_text("# nothing\n")
    box = trimesh.creation.box(extents=(10.0, 10.0, 10.0))
    lines = [f"v {x} {y} {z}" for x, y, z in box.vertices]
    lines[2] = "v nan 0 0"
    (tmp_path / "n.obj").write_text("\n".join(lines + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in box.faces]) + "\n")
    trimesh.Trimesh(box.vertices, box.faces[:-1], process=False).export(tmp_path / "o.stl")
    subst = {"{wrongcols}": "w.csv", "{badquat}": "q.csv", "{empty}": "e.obj", "{nanmesh}": "n.obj",
             "{openmesh}": "o.stl"}
    argv = [str(tmp_path / subst[a]) if a in subst else a for a in args]
    if "--out" in argv:
        argv[argv.index("--out") + 1] = str(tmp_path / "x.txt")
    assert main(["rft3d", *FAST, *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error:") and field in err
