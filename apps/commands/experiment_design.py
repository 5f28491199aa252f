"""``ultraglide experiment check|run DESIGN.toml``: a design validated, its stimuli checked, its plan printed; run.

A design that cannot run (not TOML, a key of the wrong type, a stimulus that does not deliver what it asks) exits 2
with one line naming the key or the stimulus and the figure. The threshold commands' ``--print-design`` prints the
design they run (:func:`design_from_config`).
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.options import output_option
from ultraglide.apps.cli.output import one_line, print_json
from ultraglide.apps.cli.types import PARTICIPANT, SCREEN_WIDTH_MM, Bounded, label
from ultraglide.apps.commands.serve import DEFAULT_PORT, PORT

BAD_DESIGN = 2
DESIGN_FILES = ("trials.csv", "session.json", "summary.json")
RECONNECT_S = Bounded(0.1, 86400.0, "s")
DEFAULT_RECONNECT_TIMEOUT_S = 300.0  # apps.experiment.browser's (not imported here: asyncio at every start)
SERVE_ONLY = ("host", "port", "token", "reconnect_timeout_s", "envelope_csv")


def TOKEN(text: str) -> str:  # noqa: N802 - an argparse type, named as the others
    """A token for --token: 8 to 200 URL-safe characters (letters, digits, '-', '_')."""
    if not re.fullmatch(r"[A-Za-z0-9_-]{8,200}", text):
        raise argparse.ArgumentTypeError("a token is 8 to 200 letters, digits, '-' or '_'")
    return text


def add_parsers(kinds) -> None:
    """The ``check`` and ``run`` kinds of ``ultraglide experiment``."""
    check = kinds.add_parser(
        "check", help="validate a DESIGN.toml, check its stimuli along the swipe, print its trial plan",
        description="Validate an experiment design, render every stimulus along the zone's swipe through the real "
                    "renderer and check what it delivers (contrast, mean friction, pairs), and print the trial plan. "
                    "A bad design exits 2 with one line.")
    check.add_argument("design", metavar="DESIGN.toml", help="the experiment's design (docs/experiments.md)")
    check.add_argument("--participant", type=PARTICIPANT, default="P01",
                       help="whose plan to print (a counterbalanced order depends on it; default: P01)")
    check.add_argument("--accept-check", action="store_true",
                       help="print the plan even if a stimulus fails the check (the failures are printed as warnings)")
    check.add_argument("--json", action="store_true", help="print the design, the check and the plan as one JSON "
                                                           "object")
    check.set_defaults(run=run_check)
    run = kinds.add_parser(
        "run", help="run a DESIGN.toml: a participant at the window, or a simulated observer",
        description="Run an experiment design for one participant: its stimuli are checked first (a failing design "
                    "exits 2 unless --accept-check, which records the warning in session.json), then every trial "
                    "is presented at the window or answered by a simulated observer.")
    run.add_argument("design", metavar="DESIGN.toml", help="the experiment's design (docs/experiments.md)")
    run.add_argument("--participant", type=PARTICIPANT, required=True,
                     help="participant code: letters, digits, '-', '_' or '.'")
    run.add_argument("--session", type=label, default="1", help="session label for the log (default: 1)")
    output_option(run, "--out", kind="folder", also=DESIGN_FILES, metavar="DIR", required=True,
                  help="a new directory for trials.csv, session.json and summary.json")
    run.add_argument("--observer", metavar="sim:threshold=T,slope=S,lapse=L",
                     help="a simulated observer (a dry run; default: the participant's window)")
    run.add_argument("--accept-check", action="store_true",
                     help="run even if a stimulus fails the check; the failures are recorded in session.json")
    run.add_argument("--resume", action="store_true",
                     help="continue the stopped session in --out DIR (the same design, participant and session)")
    output_option(run, "--device", kind="device", metavar="URL",
                  help="output device for the window: sim, serial:PORT, audio[...], wav:PATH or null (default: sim)")
    run.add_argument("--screen-width-mm", type=SCREEN_WIDTH_MM, help="the display's width in mm (window)")
    run.add_argument("--windowed", action="store_true", help="a window instead of full screen")
    run.add_argument("--json", action="store_true", help="print the summary as one JSON object (with --serve, the "
                                                         "page's address first, as a line of JSON)")
    served = run.add_argument_group("a participant in a browser (docs/experiments.md)")
    served.add_argument("--serve", action="store_true",
                        help="present the trials on a page the service serves (the engine on --device): the first "
                             "line printed is the page's address")
    served.add_argument("--host", help="with --serve: the address to listen on (default: 127.0.0.1, loopback; any "
                                       "other asks the page for the token printed)")
    served.add_argument("--port", type=PORT,
                        help=f"with --serve: the TCP port (default: {DEFAULT_PORT}; 0: a free one)")
    served.add_argument("--token", type=TOKEN, help="with --serve: the token the page must give (default: a random "
                                                    "one beyond loopback, none on it)")
    served.add_argument("--reconnect-timeout-s", type=RECONNECT_S, metavar="S",
                        help="with --serve: how long a session waits for a page that closed before it stops, its "
                             f"files complete (default: {DEFAULT_RECONNECT_TIMEOUT_S:g})")
    output_option(served, "--envelope-csv", kind="log", metavar="FILE.csv",
                  help="with --serve: record the envelope as it plays, as play does")
    run.set_defaults(run=run_design)


def _bad(error: BaseException) -> int:
    print(f"ultraglide experiment: error: {one_line(str(error))}", file=sys.stderr)
    return BAD_DESIGN


def _warn(message: str) -> None:
    print(f"ultraglide experiment: warning: {one_line(message)}", file=sys.stderr)


def run_check(args) -> int:
    from ultraglide.experiment import ExperimentError, check_stimuli, load_design, plan
    from ultraglide.experiment.check import refuse

    try:
        design = load_design(args.design)
    except ExperimentError as error:
        return _bad(error)
    try:
        report = check_stimuli(design)
        if not args.accept_check:
            refuse(report)
    except ExperimentError as error:
        return _bad(f"{args.design}: {error}")
    for failure in report.failures:
        _warn(f"accepted: {failure}")
    trials = plan(design, args.participant)
    if args.json:
        print_json({"design": design.as_dict(), "check": report.as_dict(), "plan": [t.as_dict() for t in trials]})
        return 0
    print(plan_text(design, report, trials, args.participant))
    return 0


def plan_text(design, report, trials, participant: str) -> str:
    """The design, its stimuli's figures and its trial plan, in words."""
    delivered = "felt through the finger's friction dynamics" if report.felt else "delivered"
    lines = [f"{design.name}: {len(trials)} trials for {participant} (seed {design.seed}, order {design.order}, "
             f"model {design.model})",
             "stimuli along the zone's swipe and the recorded paths (friction contrast asked / on the path / "
             f"{delivered}; mean ratio asked / {delivered}):"]
    for key, figure in report.figures.items():
        label = key if " along " in key else figure.label
        lines.append(f"  {label}: contrast {figure.asked_contrast:.3f} / {figure.path_contrast:.3f} / "
                     f"{figure.delivered_contrast:.3f}; mean {figure.asked_mean:.3f} / {figure.delivered_mean:.3f}; "
                     f"{figure.delivered_um_pp:.2f} µm p-p")
    for block in design.blocks:
        own = [t for t in trials if t.block == block.name]
        practice = sum(t.practice for t in own)
        question = block.question or "(default) " + block.shown_question
        lines.append(f"block {block.name}: {block.task}, {len(own)} trials ({practice} practice), conditions "
                     f"{', '.join(block.conditions)}; question: {question}")
    lines.append("trial  block  condition  zones  target  level")
    for t in trials:
        target = "" if t.target is None else (str(t.target + 1) if t.task not in ("same_different",) else
                                              ("different" if t.target else "same"))
        level = "adaptive" if t.level is None and t.task in ("staircase", "quest") and not t.practice else (
            "" if t.level is None else f"{t.level:g}")
        flags = (" practice" if t.practice else "") + (" (break before)" if t.break_before else "")
        zones = " | ".join(z or "plain glass" for z in t.zones)
        lines.append(f"{t.number}  {t.block}  {t.condition}  {zones}  {target}  {level}{flags}")
    return "\n".join(lines)


def run_design(args) -> int:
    from ultraglide.experiment import ExperimentError, check_stimuli, load_design, run
    from ultraglide.experiment.check import refuse

    try:  # the design and its stimuli checked before a window opens or a file is written
        design = load_design(args.design)
    except ExperimentError as error:
        return _bad(error)
    try:
        report = check_stimuli(design)
        if not args.accept_check:
            refuse(report)
    except ExperimentError as error:
        return _bad(f"{args.design}: {error}")
    misplaced = _misplaced(args)
    if misplaced:
        return _bad(misplaced)
    directory = Path(args.out)
    if (directory / "trials.csv").exists() and not args.resume:
        raise UsageError(f"{directory} already holds a session; continue it with --resume or choose another --out")
    if args.serve:
        if args.envelope_csv and not Path(args.envelope_csv).parent.is_dir():
            raise UsageError(f"{args.envelope_csv}: no directory {Path(args.envelope_csv).parent} to write it in")
    if args.observer:
        responder = None
    elif args.serve:
        responder = _browser(design, args)
    else:
        from ultraglide.apps.experiment.design_window import DesignWindow

        responder = DesignWindow(design, args.device or "sim", args.screen_width_mm, args.windowed)
    try:
        try:
            session = run(design, args.participant, args.session, directory, observer=args.observer,
                          responder=responder, accept_check=args.accept_check, check=report, resume=args.resume)
        finally:
            if responder is not None:
                responder.close()
    except ExperimentError as error:
        return _bad(error)
    stopped = getattr(responder, "stopped", None)
    if stopped is not None:  # a stop signal while the page waited: the files are complete, the plate at rest
        count = len(session.trials)
        print(f"ultraglide experiment: stopped after {count} trial{'' if count == 1 else 's'}; the log is in "
              f"{directory} (--resume continues it)", file=sys.stderr)
        raise stopped
    for warning in session.warnings:
        _warn(warning)
    if args.json:
        print_json({**session.summary, "directory": str(directory)})
    else:
        print(summary_text(session))
    return 0 if session.complete else 1


def _misplaced(args) -> str | None:
    """An option that belongs to another way of running, in one line naming it; None if there is none."""
    if args.observer:
        for option, value in (("--device", args.device), ("--screen-width-mm", args.screen_width_mm),
                              ("--windowed", args.windowed), ("--serve", args.serve)):
            if value:
                return (f"{option} is for the participant's window or page, and a simulated observer has none: "
                        "leave it out")
    if args.serve:
        for option, value in (("--screen-width-mm", args.screen_width_mm), ("--windowed", args.windowed)):
            if value:
                return (f"{option} is for the window; the page takes the screen's pitch as ?mm_per_px=N in its "
                        "address: leave it out")
        return None
    for key in SERVE_ONLY:
        if getattr(args, key) is not None:
            return f"--{key.replace('_', '-')} is for the participant's page: add --serve, or leave it out"
    return None


# what stops a session served to the participant's page, said when it starts (tests/test_experiment_browser.py
# checks each part: Esc on the page, a stop signal, the files, the plate, --resume)
STOP_WORDS = ("Esc on the page or Ctrl-C here stops the session, its files complete and the plate at rest "
              "(--resume goes on)")


def _browser(design, args):
    """The participant's page: the engine on the device, the service listening; its address printed first."""
    import json

    from ultraglide.apps.experiment.browser import BrowserResponder

    responder = BrowserResponder(
        design, device=args.device or "sim", host=args.host or "127.0.0.1",
        port=DEFAULT_PORT if args.port is None else args.port, token=args.token, envelope_csv=args.envelope_csv,
        reconnect_timeout_s=DEFAULT_RECONNECT_TIMEOUT_S if args.reconnect_timeout_s is None
        else args.reconnect_timeout_s)
    if args.json:
        print(json.dumps({"page": responder.page_url, "url": responder.url, "token": responder.token}), flush=True)
    else:
        print(f"{responder.page_url} {responder.url}", flush=True)
        if responder.token:
            print(f"token: {responder.token} (the page's address carries it)", flush=True)
        print(f"the participant's page: open {responder.page_url} on their screen (add &mm_per_px=N or ?mm_per_px=N "
              f"for the screen's pitch); {STOP_WORDS}", flush=True)
    return responder


def summary_text(session) -> str:
    """The session's summary in words: each block's conditions with their figures, reaction times if any."""
    state = "complete" if session.complete else f"stopped after {len(session.trials)} trials"
    lines = [f"{session.design.name}: {len(session.trials)} trials, {state}"]
    for block in session.summary["blocks"]:
        lines.append(f"block {block['block']} ({block['task']}): {block['trials']} trials")
        for item in block["conditions"]:
            name = item["condition"]
            if "threshold" in item:
                if item["threshold"] is None:
                    lines.append(f"  {name}: no threshold ({item.get('note', 'no trials')})")
                else:
                    low, high = item["ci"]
                    lines.append(f"  {name}: threshold {item['threshold']:.4g} (95 % CI {low:.4g} to {high:.4g})")
            elif "p" in item:
                low, high = item["ci"]
                what = "correct" if block["task"] == "afc" else "correct (same/different)"
                lines.append(f"  {name}: {item['positive']} of {item['trials']} {what} ({100 * item['p']:.0f} %, "
                             f"95 % CI {100 * low:.0f} to {100 * high:.0f} %)")
            elif "mean" in item:
                low, high = item["ci"]
                what = {"magnitude": "geometric mean estimate", "adjustment": "geometric mean match (contrast)"}.get(
                    block["task"], "mean rating")
                lines.append(f"  {name}: {what} {item['mean']:.3g} (95 % CI {low:.3g} to {high:.3g}) over "
                             f"{item['trials']} trials")
            else:
                lines.append(f"  {name}: no trials")
    if session.summary.get("rt_s_median") is not None:
        lines.append(f"median reaction time {session.summary['rt_s_median']:.2f} s (of "
                     f"{session.summary['rt_s_count']} trials)")
    else:
        lines.append("no reaction times logged")
    if session.directory:
        lines.append(f"files in {session.directory}: trials.csv, session.json, summary.json")
    return "\n".join(lines)


def _name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", text).strip("-") or "condition"


def design_from_config(config):
    """The design an ``experiment threshold|constant`` session runs (``--print-design``): the same stimuli, levels,
    procedure, seed and question, so that ``experiment run`` gives the same trial plan."""
    from ultraglide.experiment import Block, Condition, Design, Stimulus

    stimuli = {"stimulus": Stimulus("stimulus", config.texture)}
    if config.reference:
        stimuli["reference"] = Stimulus("reference", config.reference)
    name = _name(config.condition)
    condition = Condition(name, "stimulus", "reference" if config.reference else None, vary=config.parameter,
                          levels=tuple(config.levels) if config.method == "constant" else (),
                          level_range=tuple(config.level_range) if config.level_range else None,
                          start_level=config.start_level)
    block = Block("main", config.method, (name,), trials=config.trials, repeats=config.repeats,
                  intervals=config.intervals, rule=config.rule, function=config.function, question=config.question,
                  break_every=config.break_every)
    return Design(config.preset or f"{config.parameter} {config.method}", stimuli, {name: condition}, (block,),
                  seed=config.seed, zone_mm=tuple(config.zone_mm), gap_mm=config.gap_mm, speed_mm_s=config.speed_mm_s,
                  force_n=config.force_n, model=config.model, profile=config.profile)


__all__ = ["add_parsers", "design_from_config", "plan_text", "summary_text"]
