"""What the command prints: whole lines, however many threads print them."""

from __future__ import annotations

import json
import sys
import threading

from ultraglide.apps.cli.output import PrintableStream, print_json


def test_lines_printed_from_several_threads_never_run_into_each_other(tmp_path):
    """plate-sim prints events from its reader and output-stage threads: each line is whole."""
    path = tmp_path / "events.jsonl"
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads as often as the interpreter can
    try:
        with open(path, "w", encoding="utf-8") as file:
            stream = PrintableStream(file)  # as main installs it over standard output
            def events(source):
                for k in range(3000):
                    print_json({"source": source, "k": k}, file=stream)
            threads = [threading.Thread(target=events, args=(n,)) for n in range(4)]
            for thread in threads:
                thread.start()
            for thread in threads:
                thread.join()
    finally:
        sys.setswitchinterval(interval)
    lines = path.read_text(encoding="utf-8").splitlines()
    assert len(lines) == 4 * 3000
    assert sorted((event["source"], event["k"]) for event in map(json.loads, lines)) == \
        [(n, k) for n in range(4) for k in range(3000)]
