"""`fracture-gs view RUN_DIR`: serve a run's recorded frames in the browser (`fracture_gs.viewer`).

viser is imported only here, inside the command, so `fracture-gs --help` and every other command start without it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from . import CliError


def cmd_view(args: argparse.Namespace) -> int:
    """view: open the run's record (one sentence when it cannot be shown), then serve it until Ctrl-C."""
    from ..viewer.server import serve
    from ..viewer.store import open_run

    for flag, value in (("--preview", args.preview), ("--max-splats", args.max_splats)):
        if value < 0:
            raise CliError(f"{flag} {value} must be 0 (every Gaussian) or more; write it like {flag} 20000.")
    view = open_run(Path(args.run_dir))
    code = serve(view, host=args.host, port=args.port, preview=args.preview, max_splats=args.max_splats)
    from . import interrupt_handled

    interrupt_handled()  # Ctrl-C is how a viewer stops: exit 0, not "interrupted; nothing was written"
    return code


def check_can_serve(host: str, port: int) -> None:
    """Before a long render-sim --view run: viser is installed and the port is free, or one sentence why not."""
    from ..viewer.server import check_port

    try:
        import viser  # noqa: F401 - only whether it imports
    except ImportError:
        raise CliError(
            "--view needs viser, which is not installed; install it with pip install 'fracture-gs[view]', or drop "
            "--view and open the run later with `fracture-gs view DIR`."
        ) from None
    check_port(host, port)
