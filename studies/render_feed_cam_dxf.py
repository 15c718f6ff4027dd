"""The JB1-3 feed cam's DXF as a CAD reader shows it: the file written by
``sewmech export jb1-3 --part feed_cam --format dxf`` read back by ezdxf and rendered by its
drawing add-on (matplotlib backend) into docs/jb1-3-feed-cam-dxf.png (issue 33).

Run: ``.venv/bin/python studies/render_feed_cam_dxf.py [DXF] [PNG]`` (default: writes the DXF
to a temporary directory first). Reads nothing but the DXF: what the picture shows is what any
reader of the file gets.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent


def render(dxf: Path, png: Path) -> None:
    import ezdxf
    import matplotlib

    matplotlib.use("Agg")
    from ezdxf.addons.drawing import Frontend, RenderContext
    from ezdxf.addons.drawing.config import BackgroundPolicy, ColorPolicy, Configuration
    from ezdxf.addons.drawing.matplotlib import MatplotlibBackend
    from matplotlib.figure import Figure

    doc = ezdxf.readfile(dxf)
    fig = Figure(figsize=(7, 8))
    ax = fig.add_axes([0, 0, 1, 1])
    ctx = RenderContext(doc)
    config = Configuration(background_policy=BackgroundPolicy.WHITE,
                           color_policy=ColorPolicy.BLACK)
    Frontend(ctx, MatplotlibBackend(ax), config=config).draw_layout(doc.modelspace(),
                                                                    finalize=True)
    fig.savefig(png, dpi=110, facecolor="white")


def main(argv: list[str]) -> int:
    png = Path(argv[2]) if len(argv) > 2 else HERE.parent / "docs" / "jb1-3-feed-cam-dxf.png"
    if len(argv) > 1:
        render(Path(argv[1]), png)
        return 0
    import sewmech
    from sewmech.app.drawing.cad import machine_drawing
    from sewmech.app.files.cad import write_dxf

    with tempfile.TemporaryDirectory() as tmp:
        dxf = Path(tmp) / "jb1-3-feed_cam.dxf"
        m = sewmech.load_machine("jb1-3")
        write_dxf(machine_drawing(m, phi_deg=0.0, part="feed_cam",
                                  version=sewmech.__version__), dxf)
        render(dxf, png)
    print(f"wrote {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
