"""Modal screens: help, run metadata, a reason for marking a descent invalid."""

from __future__ import annotations

from typing import Any

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Grid, Vertical, VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Button, Input, Label, Static

from station.session.records import METADATA_FIELDS

HELP = """\
[b]station[/b] — trackside measurement of ski friction

[b]Panels[/b]
  header     connection to the timer, lines and impulses received
  descent    the open descent: photocells passed, with their times
  result     the latest fit: μ, CdA and v0 with 90 % intervals, status
  residuals  computed minus measured time at each photocell
  speed      the fitted skier's speed along the run
  table      every descent of the session; select one with ↑ ↓

[b]Keys[/b]
  m   run metadata (skier, mass, ski, wax, air, snow, notes) for the following descents
  i   mark the selected descent invalid, with a reason (again: valid)
  v   refit the selected descent with velocity-dependent friction (again: constant)
  e   export the session's results CSV
  c   compare the items (ski / wax) of the session: joint fit, Δμ, ranking, drift
  ?   this help        q   quit

Every byte from the timer is recorded before it is parsed; a session replays with
[i]station replay SESSION --ui[/i]. Statuses: ok, ill-conditioned (a parameter not
identifiable: shown as —), lift-off, stopped, too-few-photocells, not-converged, aborted,
error (the fit failed: the reason is in the notes; the recording goes on).
"""

#: the form's labels, from the one table of metadata keys
LABELS = {f.key: f.title for f in METADATA_FIELDS}
KINDS = {f.key: f.kind for f in METADATA_FIELDS}


class HelpScreen(ModalScreen[None]):
    BINDINGS = [Binding("escape,q,question_mark", "dismiss", "close")]

    def compose(self) -> ComposeResult:
        with VerticalScroll(id="help"):
            yield Static(HELP)
            yield Button("Close", id="close")

    def on_button_pressed(self, _event: Button.Pressed) -> None:
        self.dismiss(None)


class MetadataScreen(ModalScreen[dict[str, Any] | None]):
    """Edit the metadata for the descents that start from now on."""

    BINDINGS = [Binding("escape", "cancel", "cancel")]

    def __init__(self, current: dict[str, Any], next_number: int) -> None:
        super().__init__()
        self.current = current
        self.next_number = next_number

    def compose(self) -> ComposeResult:
        with VerticalScroll(id="form"):
            yield Label(f"Run metadata for descent {self.next_number} and after  (Enter saves)")
            with Grid(id="fields"):
                for key in KINDS:
                    yield Label(LABELS[key], markup=False)  # "[hPa]" is a unit, not markup
                    value = self.current.get(key)
                    yield Input(
                        ""
                        if value is None
                        else f"{value:g}"
                        if isinstance(value, float)
                        else str(value),
                        id=f"f_{key}",
                        type="number" if KINDS[key] is float else "text",
                        valid_empty=True,  # every field is optional
                    )
            yield Label("", id="error")
            with Grid(id="buttons"):
                yield Button("Save", variant="primary", id="save")
                yield Button("Cancel", id="cancel")

    def on_mount(self) -> None:
        self.query_one("#f_skier", Input).focus()  # type at once; Enter saves

    def _values(self) -> dict[str, Any] | None:
        out: dict[str, Any] = {}
        for key, kind in KINDS.items():
            text = self.query_one(f"#f_{key}", Input).value.strip()
            if text == "":
                continue
            if kind is float:
                try:
                    out[key] = float(text)
                except ValueError:
                    self.query_one("#error", Label).update(
                        f"{LABELS[key]}: {text!r} is not a number"
                    )
                    return None
            else:
                out[key] = text
        if "mass_kg" in out and out["mass_kg"] <= 0:
            self.query_one("#error", Label).update("mass must be greater than 0")
            return None
        if out.get("wind_ms") and "wind_from_deg" not in out:
            self.query_one("#error", Label).update("wind speed needs the direction it comes from")
            return None
        if "humidity_pct" in out and not 0 <= out["humidity_pct"] <= 100:
            self.query_one("#error", Label).update("humidity must lie between 0 and 100 %")
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


class ComparisonScreen(ModalScreen[None]):
    """Which ski or wax glides better: the joint fit of the session, updated after each descent."""

    BINDINGS = [Binding("escape,c,q", "dismiss", "close")]

    def __init__(self, text: str) -> None:
        super().__init__()
        self.text = text

    def compose(self) -> ComposeResult:
        with VerticalScroll(id="comparison"):
            yield Static(self.text, id="comparison_text", markup=False)
            yield Button("Close", id="close")

    def update(self, text: str) -> None:
        self.text = text
        self.query_one("#comparison_text", Static).update(text)

    def on_button_pressed(self, _event: Button.Pressed) -> None:
        self.dismiss(None)
