"""`runtime.import_in_background`: a run on a GPU loads the modules a fracture event needs beside its main thread."""


def test_import_in_background_loads_modules_on_its_own_thread(tmp_path, monkeypatch):
    """`import_in_background` imports each module on a daemon thread of its own (the module runs there, not on the
    caller's); a module that fails to import is skipped and the next one still loads."""
    import sys
    import threading

    from fracture_gs.runtime import import_in_background

    (tmp_path / "fgs_bg_probe.py").write_text("import threading\nTHREAD = threading.current_thread().name\n")
    (tmp_path / "fgs_bg_broken.py").write_text("raise RuntimeError('broken on purpose')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    thread = import_in_background("fgs_bg_broken", "fgs_bg_probe")
    assert thread.daemon
    thread.join(30)
    assert "fgs_bg_broken" not in sys.modules
    assert sys.modules["fgs_bg_probe"].THREAD == thread.name != threading.current_thread().name
    sys.modules.pop("fgs_bg_probe")
