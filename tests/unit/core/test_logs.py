"""receiver.logs: the batch runner's capture sees only its own thread's records; the CLI handler prints plain
lines on the current stdout."""
import io
import logging
import threading

from receiver.logs import capture, setup_cli


def test_capture_keeps_the_calling_threads_records_only():
    log = logging.getLogger("receiver.test_logs")
    buf = io.StringIO()
    with capture(buf):
        log.info("mine")
        t = threading.Thread(target=lambda: log.info("other thread"))
        t.start()
        t.join()
        log.debug("below the level")
    log.info("after the capture")
    assert buf.getvalue() == "mine\n"


def test_cli_handler_prints_plain_lines(capsys):
    setup_cli()
    setup_cli()                                  # idempotent: one line per record, not two
    logging.getLogger("receiver.test_logs").info("wrote x.nmea (rows 3)")
    assert capsys.readouterr().out == "wrote x.nmea (rows 3)\n"
