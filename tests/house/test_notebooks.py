"""Every notebook in notebooks/ runs top to bottom in a real Jupyter kernel (nbclient + ipykernel),
started in the repository's root and in an empty temporary folder (issue 22), and prints no warning.

A cell that raises fails the test with the cell's traceback; so does a warning, whether this process
emits it (nbformat reading a notebook, nbclient running it) or the kernel prints it into a cell's
output. The kernel inherits this process's environment (PYTHONPATH included), so it imports the
same warp_spt; its working directory is not the notebooks' folder, so a notebook cannot rely on
files beside it (it finds its data through the package, e.g. ``warp_spt.demo``).
"""

from __future__ import annotations

import contextlib
import re
import tempfile
import warnings
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
NOTEBOOKS = sorted((REPO / "notebooks").glob("*.ipynb"))
CELL_TIMEOUT = 600      # seconds per cell: generous for a loaded 2-core CI machine
WARNING = re.compile(r"\w*Warning\b")
# what makes a notebook depend on where it was started or on files outside the package
CWD_TRICKS = ("sys.path", "chdir", "cwd()", "getcwd", "../", "..\\")


def _jupyter():
    nbformat = pytest.importorskip("nbformat", reason="the test extra installs nbformat, nbclient and ipykernel")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    return nbformat, nbclient


def read(path: Path):
    """The notebook, read as nbformat 4; a warning while reading (a cell without an id) fails."""
    nbformat, _ = _jupyter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        nb = nbformat.read(path, as_version=4)
    assert not caught, f"{path.name}: {[f'{w.category.__name__}: {w.message}' for w in caught]}"
    return nb


@contextlib.contextmanager
def kernel_client(nb, cwd: Path, timeout: int = CELL_TIMEOUT):
    """An nbclient client whose kernel starts in ``cwd`` and talks over local sockets (IPC) in a
    folder of their own: over TCP, ipykernel logs a warning that the traffic is not encrypted."""
    from traitlets.config import Config

    _, nbclient = _jupyter()
    with tempfile.TemporaryDirectory(prefix="nbk") as sockets:
        config = Config({"KernelManager": {"transport": "ipc", "ip": str(Path(sockets) / "kernel")}})
        yield nbclient.NotebookClient(nb, config=config, timeout=timeout, kernel_name="python3",
                                      resources={"metadata": {"path": str(cwd)}})


def execute(nb, cwd: Path, name: str = "notebook"):
    """Run ``nb`` in a fresh kernel started in ``cwd``; fail on an error or on any warning."""
    _, nbclient = _jupyter()
    with kernel_client(nb, cwd) as client, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            client.execute()
        except nbclient.exceptions.CellExecutionError as err:
            pytest.fail(f"{name}: a cell failed:\n{err}", pytrace=False)
    assert not caught, f"{name}: {[f'{w.category.__name__}: {w.message}' for w in caught]}"
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    errors = [o for o in outputs if o.output_type == "error"]
    assert not errors, errors
    printed = [o.text for o in outputs if o.output_type == "stream" and WARNING.search(o.text)]
    assert not printed, f"{name}: the kernel printed a warning:\n" + "\n".join(printed)
    return outputs


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_runs(path, tmp_path):
    """Each notebook runs in a kernel started in an empty folder: neither notebooks/ nor the
    repository (where a relative path would happen to work); once, as the notebooks are most of
    this file's time."""
    execute(read(path), tmp_path, path.name)


def test_there_is_a_notebook():
    assert NOTEBOOKS, "notebooks/ should hold at least one notebook"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_is_normalised(path):
    """nbformat 4.5 or later, and every cell has its own id: nbformat reads it without a warning."""
    nb = read(path)
    assert (nb.nbformat, nb.nbformat_minor) >= (4, 5)
    ids = [c.get("id") for c in nb.cells]
    assert all(ids) and len(set(ids)) == len(ids), ids


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_does_not_depend_on_where_it_runs(path):
    """No notebook edits sys.path, changes or reads the working directory, or reaches for files
    above it: the installed package is all it needs, wherever Jupyter starts its kernel."""
    code = [c.source for c in read(path).cells if c.cell_type == "code"]
    found = [(trick, src.splitlines()[0]) for src in code for trick in CWD_TRICKS if trick in src]
    assert not found, found


def test_explore_teaches_render_gradients():
    """explore.ipynb shows gradients by parameter name (warp_spt.render_gradients), not the old
    wp.Tape workflow, and says in a markdown cell what each code cell shows."""
    cells = read(REPO / "notebooks" / "explore.ipynb").cells
    code = "\n".join(c.source for c in cells if c.cell_type == "code")
    assert "warp_spt.render_gradients(" in code and "warp_spt.parameters(" in code
    for old in ("wp.Tape", "tape.backward", "render_differentiable", "enable_material_gradients", "import warp "):
        assert old not in code, old
    unexplained = [c.source.splitlines()[0] for prev, c in zip(cells, cells[1:])
                   if c.cell_type == "code" and prev.cell_type != "markdown"]
    assert cells[0].cell_type == "markdown" and not unexplained, unexplained


def test_a_failing_cell_fails(tmp_path):
    nbformat, nbclient = _jupyter()
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("x = 1"),
                                         nbformat.v4.new_code_cell("raise ValueError('broken cell')")])
    with kernel_client(nb, tmp_path, timeout=60) as client:
        with pytest.raises(nbclient.exceptions.CellExecutionError, match="broken cell"):
            client.execute()


def test_a_warning_in_a_cell_fails(tmp_path):
    nbformat, _ = _jupyter()
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("import warnings; warnings.warn('odd')")])
    with pytest.raises(AssertionError, match="UserWarning: odd"):
        execute(nb, tmp_path)


@pytest.mark.parametrize("widgets", [True, False], ids=["ipywidgets", "no-ipywidgets"])
def test_progress_bar_in_jupyter_warns_not(widgets, tmp_path):
    """progress=True in Jupyter: a widget with ipywidgets (the notebook extra), else a text bar on
    stderr, and no TqdmWarning ('IProgress not found') either way."""
    nbformat, _ = _jupyter()
    hide = "" if widgets else "import sys; sys.modules['ipywidgets'] = None   # as if it were not installed\n"
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(
        hide + "import warnings\n"
        "from warp_spt.runtime.progress import ProgressBar\n"
        "with warnings.catch_warnings(record=True) as caught:\n"
        "    warnings.simplefilter('always')\n"
        "    bar = ProgressBar(1000, delay=0.0)\n"
        "    bar(1, 2); bar(2, 2); bar.close()\n"
        "print('caught', [f'{w.category.__name__}: {w.message}' for w in caught])")])
    outputs = execute(nb, tmp_path)
    stdout = "".join(o.text for o in outputs if o.output_type == "stream" and o.name == "stdout")
    stderr = "".join(o.text for o in outputs if o.output_type == "stream" and o.name == "stderr")
    assert "caught []" in stdout, stdout
    widget = [o for o in outputs if o.output_type == "display_data"
              and "application/vnd.jupyter.widget-view+json" in o.data]
    if widgets:
        assert widget and not stderr, (outputs, stderr)
    else:
        assert not widget and "rendering: 100%" in stderr, (outputs, stderr)
