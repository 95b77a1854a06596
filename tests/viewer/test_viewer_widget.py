"""The viewer as a Jupyter widget in a real kernel (nbclient + ipykernel), issue 23.

There is no front end in the test, so the cells play its part: they hand the widget the messages
viewer.js would send (``_handle_custom_msg`` is what ipywidgets calls with a front end's custom
message) and check what the widget sent back through the kernel's comm.
"""

from __future__ import annotations

import pytest

nbformat = pytest.importorskip("nbformat", reason="the test extra installs nbformat, nbclient and ipykernel")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("ipykernel")
pytest.importorskip("anywidget", reason="the view extra installs anywidget")

CELLS = [
    """
import warp_spt
from warp_spt.demo import demo_files
from warp_spt.viewer import Viewer

scene = warp_spt.load_scene(*demo_files(), default_material="auto")
viewer = Viewer(scene, width=48, height=36, max_spp=16)
sent = []                                           # what the widget sends its front end
to_page = viewer.send
viewer.send = lambda content, buffers=None: (sent.append((content["type"], len(buffers or []))),
                                             to_page(content, buffers))
viewer
""",
    """
first = viewer.wait_for(8, timeout=600)            # it renders, in the kernel, with no page open
assert first.image.shape == (36, 48, 3) and first.spp_total >= 8
before = viewer.camera
assert isinstance(before, warp_spt.Camera)
for message in ({"type": "interact", "active": True}, {"type": "orbit", "dx": 0.1, "dy": 0.05},
                {"type": "orbit", "dx": 0.05, "dy": 0.0}, {"type": "interact", "active": False}):
    viewer._handle_custom_msg(message, [])          # what a drag on the page sends
after = viewer.camera
assert after.position != before.position and after.direction != before.direction
assert abs(sum((a - t) ** 2 for a, t in zip(after.position, viewer.session.state()["camera"]["target"])) ** 0.5
           - sum((b - t) ** 2 for b, t in zip(before.position, viewer.session.state()["camera"]["target"])) ** 0.5) < 1e-6
again = viewer.wait_for(8, timeout=600)
assert not (again.image == first.image).all()
assert ("frame", 1) in sent and ("state", 0) in sent
print(viewer.command_line(spp=32))
""",
    """
viewer._handle_custom_msg({"type": "set", "key": "max_depth", "value": -3}, [])   # a bad value: a notice
assert ("notice", 0) in sent and viewer.session.settings.max_depth == 6
viewer.close()
""",
]


def test_the_widget_renders_and_follows_a_drag(tmp_path):
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(c) for c in CELLS])
    client = nbclient.NotebookClient(nb, timeout=900, kernel_name="python3",
                                     resources={"metadata": {"path": str(tmp_path)}})
    try:
        client.execute()
    except nbclient.exceptions.CellExecutionError as err:
        pytest.fail(f"a cell failed:\n{err}", pytrace=False)
    shown = nb.cells[0].outputs[0]["data"]
    assert "application/vnd.jupyter.widget-view+json" in shown          # displayed as a widget
    printed = "".join(o.get("text", "") for o in nb.cells[1].outputs)
    assert printed.startswith("warp-spt -cam ") and "-sr 32" in printed
