"""Modal screens: help, run metadata, a reason for marking a descent invalid."""

from __future__ import annotations

import math
from typing import Any

from rich.segment import Segment
from rich.style import Style as RichStyle
from textual.app import ComposeResult
from textual.binding import Binding
from textual.cache import LRUCache
from textual.color import Color
from textual.containers import Grid, Horizontal, ScrollableContainer, Vertical, VerticalScroll
from textual.css.styles import RulesMap
from textual.renderables.background_screen import BackgroundScreen
from textual.screen import ModalScreen, Screen
from textual.strip import Strip
from textual.style import Style
from textual.validation import ValidationResult, Validator
from textual.visual import RenderOptions, Visual
from textual.widgets import Button, Footer, Header, Input, Label, RichLog, Static

from station.errors import InputError
from station.limits import PLAUSIBLE
from station.numbers import parse_number
from station.report.comparison_text import headline
from station.session.records import METADATA_FIELDS, choice
from station.ui.table import ResultsTable

#: fits 80×24 without scrolling (tests/test_ui.py checks it)
HELP = """\
[b]station[/b] — trackside measurement of ski friction

[b]Keys[/b]  ↑ ↓  select a descent: the result panel, i and v are about it
      m    metadata (skier, mass, ski, wax, air, notes) for next descents
      i    mark the selected descent invalid, with a reason (again: valid)
      v    refit the selected descent with μ + μ1·v (again: constant μ)
      e    write the results CSV    c  compare the skis / waxes of the day
      ?    this help                q  quit: the open descent is ended

[b]Panels[/b] status: timer, impulses, edits, unparsed · the open descent ·
      result: μ, CdA, v0 with 90 % intervals; mass, air density, g; flags ·
      residuals: computed − measured time per photocell · speed on the run
[b]Table[/b]  st: ok · ill ill-conditioned (— where not identifiable) · lift
      lift-off · stop · few too few photocells · nc not converged · abort
      · poor residuals beyond the timer's precision · ERR the fit failed
      · INV marked invalid; v velocity model; ! flags

Every byte from the timer is recorded first: [i]station replay SESSION --ui[/i]"""

#: the form's labels, from the one table of metadata keys
LABELS = {f.key: f.title for f in METADATA_FIELDS}
KINDS = {f.key: f.kind for f in METADATA_FIELDS}
#: the classes a field takes (snow type, wetness, hand hardness), from the same table
CHOICES = {f.key: f.choices for f in METADATA_FIELDS if f.choices}


class HelpScreen(ModalScreen[None]):
    BINDINGS = [Binding("escape,q,question_mark", "dismiss", "close")]

    def compose(self) -> ComposeResult:
        with Vertical(id="help"):
            with VerticalScroll(classes="dialog-body"):
                yield Static(HELP)
            yield Button("Close", id="close", compact=True)

    def on_button_pressed(self, _event: Button.Pressed) -> None:
        self.dismiss(None)


#: plausible ranges of the number fields (min, max), the station's one table
RANGES: dict[str, tuple[float, float]] = {k: (lo, hi) for k, (lo, hi, _) in PLAUSIBLE.items()}


class NumberField(Validator):
    """A metadata number: a decimal point or comma, within a plausible range. Its message is
    shown in the field's own border, so it is seen where the eyes are, at any terminal size."""

    def __init__(self, key: str) -> None:
        super().__init__()
        self.key = key

    def validate(self, value: str) -> ValidationResult:
        if not value.strip():
            return self.success()
        try:  # a decimal point or comma (72,5 on a German laptop), never nan or inf
            number = parse_number(value)
        except ValueError as exc:  # short: it must fit the field's border at 80 columns
            why = str(exc)
            if "both" in why:
                return self.failure("point or comma, not both")
            return self.failure("too large" if "too large" in why else "not a number")
        lo, hi = RANGES.get(self.key, (-math.inf, math.inf))
        if not lo <= number <= hi:
            return self.failure(f"must lie between {lo:g} and {hi:g}")
        return self.success()


class MetadataScreen(ModalScreen[dict[str, Any] | None]):
    """Edit the metadata for the descents that start from now on.

    Only what the engineer changed is returned: a pre-filled field saved as it was must not
    become a new entry that overrides what was entered for later descents (the demo's
    rotation of pairs, a refit's mass)."""

    BINDINGS = [Binding("escape", "cancel", "cancel")]

    def __init__(self, current: dict[str, Any], next_number: int) -> None:
        super().__init__()
        self.current = current
        self.next_number = next_number
        self.initial: dict[str, str] = {}

    @staticmethod
    def _text(value: Any) -> str:
        if value is None:
            return ""
        return f"{value:g}" if isinstance(value, float) else str(value)

    def title_text(self) -> str:
        return f"Run metadata from descent {self.next_number} on  (Enter saves, Esc cancels)"

    def set_next(self, next_number: int) -> None:
        """A descent started while the form is open: it applies from the one after."""
        if next_number != self.next_number:
            self.next_number = next_number
            self.query_one("#title", Label).update(self.title_text())

    def compose(self) -> ComposeResult:
        # two columns of fields: the whole form fits 80×24 without scrolling
        with VerticalScroll(id="form"):
            yield Label(self.title_text(), id="title", markup=False)
            yield Label("", id="error", markup=False)  # "[kg]" in a message is a unit
            with Grid(id="fields"):
                for key in KINDS:
                    yield Label(LABELS[key], markup=False)  # "[hPa]" is a unit, not markup
                    number = KINDS[key] is float
                    self.initial[key] = self._text(self.current.get(key))
                    field = Input(
                        self.initial[key],
                        id=f"f_{key}",
                        # text, not type="number": that drops a typed comma, so 72,5 became 725
                        type="text",
                        validators=[NumberField(key)] if number else None,
                        valid_empty=True,  # every field is optional
                    )
                    yield field
            with Horizontal(id="buttons"):
                yield Button("Save", variant="primary", id="save", compact=True)
                yield Button("Cancel", id="cancel", compact=True)

    def on_mount(self) -> None:
        self.query_one("#f_skier", Input).focus()  # type at once; Enter saves

    def on_input_changed(self, event: Input.Changed) -> None:
        """The message next to the field while typing, not only when saving."""
        result = event.validation_result
        if result is not None and not result.is_valid:
            event.input.border_subtitle = result.failure_descriptions[0]
        else:
            event.input.border_subtitle = ""
            self.query_one("#error", Label).update("")

    def _refuse(self, key: str, message: str) -> None:
        field = self.query_one(f"#f_{key}", Input)
        field.border_subtitle = message
        field.add_class("-invalid")
        field.focus()  # scrolls it into view in a form taller than the terminal
        text = f"{LABELS[key]}: {field.value.strip()!r}: {message}"
        self.query_one("#error", Label).update(text)
        self.notify(text, severity="error", timeout=4)

    def _values(self) -> dict[str, Any] | None:
        out: dict[str, Any] = {}
        for key, kind in KINDS.items():
            text = self.query_one(f"#f_{key}", Input).value.strip()
            if text == "" or text == self.initial.get(key, "").strip():
                continue  # empty, or pre-filled and left as it was
            if kind is float:
                result = NumberField(key).validate(text)
                if not result.is_valid:
                    self._refuse(key, result.failure_descriptions[0])
                    return None
                out[key] = parse_number(text)
            elif key in CHOICES:
                try:
                    out[key] = choice(text, CHOICES[key], key)
                except InputError:
                    self._refuse(key, " ".join(CHOICES[key]))
                    return None
            else:
                out[key] = text
        wind_dir = "wind_from_deg" in out or self.initial.get("wind_from_deg", "").strip()
        if out.get("wind_ms") and not wind_dir:
            self._refuse("wind_from_deg", "a wind speed needs the direction it comes from")
            return None
        return out

    def on_input_submitted(self, _event: Input.Submitted) -> None:
        self.action_save()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        if event.button.id == "save":
            self.action_save()
        else:
            self.dismiss(None)

    def action_save(self) -> None:
        values = self._values()
        if values is not None:
            self.dismiss(values)

    def action_cancel(self) -> None:
        self.dismiss(None)


class ReasonScreen(ModalScreen[str | None]):
    """Why a descent is invalid (a fall, edging, wind gust, someone on the track …)."""

    BINDINGS = [Binding("escape", "cancel", "cancel")]

    def __init__(self, number: int) -> None:
        super().__init__()
        self.number = number

    def compose(self) -> ComposeResult:
        with Vertical(id="reason"):
            yield Label(f"Mark descent {self.number} invalid. Reason (Enter saves, Esc cancels):")
            yield Input(placeholder="e.g. skier edged after PC6", id="reason_input")

    def on_input_submitted(self, event: Input.Submitted) -> None:
        self.dismiss(event.value.strip() or "marked invalid")

    def action_cancel(self) -> None:
        self.dismiss(None)


#: below this terminal width the comparison dialog (110 wide, with borders) fills it
FULL_WIDTH = 114
#: dimmed lines of the screen behind a dialog kept (a 40-line screen, a few frames' worth)
DIMMED_LINES = 256


def _dim_line(strip: Strip, color: Color, base: RichStyle, width: int) -> Strip:
    """One line of the screen behind, dimmed as Textual dims it (``BackgroundScreen``'s tint,
    then the dialog screen's own style, as ``RichVisual`` applies it, cropped to ``width``)."""
    tinted = BackgroundScreen.process_segments(strip, color)
    if base:
        tinted = (Segment(text, base + style, None) for text, style, _ in tinted)
    lines = list(Segment.split_and_crop_lines(tinted, width, include_new_lines=False, pad=False))
    return Strip(lines[0] if lines else [])


class DimmedScreen(Visual):
    """The screen behind a dialog, dimmed: what Textual's ``BackgroundScreen`` draws, line by
    line the same, but each line dimmed once and kept by what it shows.

    Textual draws a dialog's translucent background by rendering the whole screen behind it
    and tinting every segment again, whenever anything behind it changes: with the comparison
    open all day, every impulse, status line and new table row (the fit the engineer waits
    for) cost 30–45 ms of the UI's thread at 120×40. Here only the lines that changed are
    tinted; the screen behind is still composed (its widgets keep their own caches), so what
    is seen through the dialog is what Textual shows, and the table's new row is drawn."""

    def __init__(self, base: Screen, color: Color, cache: LRUCache[Any, Strip]) -> None:
        self.base = base
        self.color = color
        self.cache = cache

    def render_strips(
        self, width: int, height: int | None, style: Style, options: RenderOptions
    ) -> list[Strip]:
        base = style.rich_style
        color, cache = self.color, self.cache
        out = []
        for strip in self.base._compositor.render_strips():
            key = (tuple(strip), color, base, width)
            line = cache.get(key)
            if line is None:
                line = cache[key] = _dim_line(strip, color, base, width)
            out.append(line)
        return out if height is None else out[:height]

    def get_optimal_width(self, rules: RulesMap, container_width: int) -> int:
        return container_width

    def get_height(self, rules: RulesMap, width: int) -> int:
        return self.base._compositor.size.height


class ComparisonScreen(ModalScreen[None]):
    """Which ski or wax glides better: the joint fit of the session, updated after each descent."""

    BINDINGS = [Binding("escape,c,q", "dismiss", "close")]

    def __init__(self, text: str) -> None:
        super().__init__()
        self.text = text
        self._dimmed: LRUCache[Any, Strip] = LRUCache(DIMMED_LINES)

    def render(self) -> Any:
        """The screen behind, dimmed line by line (:class:`DimmedScreen`)."""
        behind = super().render()
        if isinstance(behind, BackgroundScreen):
            return DimmedScreen(behind.screen, behind.color, self._dimmed)
        return behind

    def compose(self) -> ComposeResult:
        # the text scrolls, the Close button stays in sight below it at any size
        with Vertical(id="comparison"):
            with ScrollableContainer(classes="dialog-body"):  # long lines wrap; it scrolls
                yield Static(self.text, id="comparison_text", markup=False)
            yield Button("Close", id="close", compact=True)

    def on_mount(self) -> None:
        self._fit_width()

    def on_resize(self, _event: object) -> None:
        self._fit_width()

    def _fit_width(self) -> None:
        """At 80 columns the dialog is the terminal's width: its side borders give the text
        the columns the ranking's header needs."""
        self.set_class(self.app.size.width < FULL_WIDTH, "full-width")

    def update(self, text: str) -> None:
        self.text = text
        # not composed yet, or being closed: what it composes with is the text just kept
        for box in self.query("#comparison_text").results(Static):
            box.update(text)

    def on_button_pressed(self, _event: Button.Pressed) -> None:
        self.dismiss(None)


class MainScreen(Screen):
    """The one screen of the station; modal screens go on top of it."""

    def compose(self) -> ComposeResult:
        yield Header(show_clock=False)
        yield Static("", id="status", markup=False)
        yield Static(headline(None), id="answer", markup=False)  # the day's answer, always
        # markup=False: "[0.2238, 0.2249]", "x [m]" and a port name are text, not markup
        with Horizontal(id="top"):
            with Vertical(id="left"):
                yield Static("waiting for the first descent", id="progress", markup=False)
                yield Static("no result yet", id="result", markup=False)
                with Horizontal(id="plots"):
                    yield Static("", id="residuals", markup=False)
                    yield Static("", id="speed", markup=False)
            yield RichLog(id="log", max_lines=500, markup=False, wrap=False)
        yield ResultsTable(id="table", cursor_type="row", zebra_stripes=True, cell_padding=0)
        # compact, without the command palette's key: at 80 columns "q Quit" stays in sight
        yield Footer(compact=True, show_command_palette=False)

    def on_resize(self, _event: object) -> None:
        self.app.on_resize()  # type: ignore[attr-defined]

    def on_screen_resume(self, _event: object) -> None:
        self.app.on_main_uncovered()  # type: ignore[attr-defined]
