"""ray_output_to: Ray's own driver-side messages go to the sweep folder's log (no Ray needed:
its error listener is a thread named ``ray_…`` that prints, its logger is ``ray``)."""

from __future__ import annotations

import logging
import sys
import threading

from experiments.studies.ray_log import ray_output_to

RAYLET_BLOCK = "(raylet) Raylet is terminated. Termination is unexpected.\n    [state-dump] ...\n"


def test_rays_threads_and_logger_write_to_the_log_and_the_rest_is_untouched(tmp_path, capsys):
    log = tmp_path / "ray.log"
    ray_logger = logging.getLogger("ray")
    before = ray_logger.handlers[:], ray_logger.propagate
    out = sys.stdout
    with ray_output_to(log):
        listener = threading.Thread(
            target=lambda: print(RAYLET_BLOCK, end=""), name="ray_listen_error_messages"
        )
        listener.start()
        listener.join()
        logging.getLogger("ray._private.worker").warning("Started a local Ray instance.")
        print("wander's own line")
        other = threading.Thread(target=lambda: print("another thread's line"), name="w")
        other.start()
        other.join()
    assert sys.stdout is out
    assert (ray_logger.handlers, ray_logger.propagate) == before
    captured = capsys.readouterr()
    assert captured.out == "wander's own line\nanother thread's line\n"
    assert captured.err == ""
    text = log.read_text()
    assert text.startswith(RAYLET_BLOCK)
    assert text.splitlines()[2].endswith(
        "WARNING ray._private.worker: Started a local Ray instance."
    )
    assert len(text.splitlines()) == 3
    with ray_output_to(log):  # appended, never truncated: a resumed sweep keeps the first
        logging.getLogger("ray").error("again")
    assert log.read_text().startswith(text) and log.read_text().endswith("ERROR ray: again\n")
