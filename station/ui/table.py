"""The descents table: Textual's DataTable, with cells drawn without Rich's layout.

A DataTable forgets every cell it has drawn whenever a row is added or a cell changes (its
caches are keyed by a count of updates), and draws each again through Rich's console (markup,
padding, wrapping): ~1 ms a cell, 20 rows × 11 columns after every descent, most of the UI's
time from a descent's last impulse to its row on the screen. The station's cells are one line
of plain text each, already justified (``app.cell``): drawn here as one segment cropped or
padded to the column's width, and kept by what they show, so a new descent draws its own row
and reuses the others. The segments are those Rich made (the line is simplified into the same
strip), and text in a cell is text: a note "[kg]" is not taken for markup.

DataTable has no public hook for how it lays out and draws its lines: the five methods with a
leading underscore below override its private ones, each with its reason; the rest is public.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, Self

from rich.cells import set_cell_size
from rich.segment import Segment
from rich.style import Style
from textual.cache import LRUCache
from textual.geometry import Region, Size
from textual.strip import Strip
from textual.widgets import DataTable
from textual.widgets.data_table import CellDoesNotExist, Row, RowKey


class ResultsTable(DataTable[str]):
    """A DataTable whose cells are single lines of plain text (``str``)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        # set first: DataTable's own __init__ may add rows or clear the table
        self._plain_cells: LRUCache[tuple[object, ...], list[list[Segment]]] = LRUCache(4000)
        self._plain_lines: LRUCache[tuple[object, ...], Strip] = LRUCache(1000)
        self._labelled = False  # a row with a label was added (drawn by DataTable then)
        self._reset_order()
        super().__init__(*args, **kwargs)

    def clear(self, columns: bool = False) -> Self:
        super().clear(columns)
        self._plain_cells.clear()
        self._plain_lines.clear()
        self._labelled = False
        self._reset_order()
        return self

    def notify_style_update(self) -> None:
        """A new theme or style: the lines and cells kept are forgotten. DataTable clears its
        own caches here, not through ``_clear_caches``, and ours are keyed by the table's base
        style, not by the cursor's or the header's: a theme that changes those but not the
        table's background kept the old colours."""
        super().notify_style_update()
        self._plain_cells.clear()
        self._plain_lines.clear()

    # -- rows in order, and the row on each line: extended as rows are added

    def _reset_order(self) -> None:
        self._order: list[Row] | None = None  # None: taken from DataTable when next asked
        self._offsets: list[tuple[RowKey, int]] = []
        self._uniform = True  # every row one line high

    def _append(self, order: list[Row], row: Row) -> None:
        order.append(row)
        self._uniform = self._uniform and row.height == 1 and not row.auto_height

    def add_row(self, *cells: Any, height: int | None = 1, key: str | None = None,
                label: Any = None) -> RowKey:  # fmt: skip
        row_key = super().add_row(*cells, height=height, key=key, label=label)
        self._labelled = self._labelled or label is not None
        order = self._order  # None, or taken from DataTable with this row already in it
        if order is not None and len(order) < self.row_count:  # added at the end, as all are
            self._append(order, self.rows[row_key])
        return row_key

    @property
    def ordered_rows(self) -> list[Row]:
        """The rows as they are shown. DataTable builds this list (and the row of every line
        of the table) again after every added row or changed cell: 2000 rows looked up for
        each descent near descent 2000. The station's rows are only ever added at the end, so
        the list is extended as they are; after a sort, a removal or a clear it is DataTable's
        own, taken once."""
        if self._order is None:
            self._order = []
            for row in super().ordered_rows:
                self._append(self._order, row)
        return self._order

    @property
    def _y_offsets(self) -> list[tuple[RowKey, int]]:
        # private: DataTable's row of each line, rebuilt for every row after each update
        order = self.ordered_rows
        if not self._uniform:
            return [(row.key, y) for row in order for y in range(row.height)]
        offsets = self._offsets
        offsets.extend((row.key, 0) for row in order[len(offsets) :])
        return offsets

    def _get_row_region(self, row_index: int) -> Region:
        """A row's place: its index below the header when every row is one line (DataTable
        adds up the heights of the rows above it, in this private method of its scrolling)."""
        self.ordered_rows  # noqa: B018 - brings the rows' heights up to date
        if not self._uniform:
            return super()._get_row_region(row_index)
        if not self.is_valid_row_index(row_index):
            return Region(0, 0, 0, 0)
        width = sum(c.get_render_width(self) for c in self.columns.values())
        width += self._row_label_column_width  # private: the labels' width, DataTable's to know
        y = row_index + (self.header_height if self.show_header else 0)
        return Region(0, y, max(self.size.width, width), 1)

    def sort(self, *args: Any, **kwargs: Any) -> Self:
        super().sort(*args, **kwargs)
        self._reset_order()
        return self

    def remove_row(self, row_key: RowKey | str) -> None:
        super().remove_row(row_key)
        self._reset_order()

    def _update_dimensions(self, new_rows: Iterable[RowKey]) -> None:
        """The table's size after rows were added. DataTable measures every cell of each new
        row for the widths of auto-sized columns and keeps what it measured (11 Rich Texts a
        row, kept for the last 1000 rows: objects every full garbage collection walks), in this
        private method called after rows are added. The station's columns have fixed widths and
        its rows one line: nothing to measure."""
        rows = list(new_rows)
        fixed = not any(c.auto_width for c in self.columns.values())
        plain = all(
            (row := self.rows.get(k)) is None or (row.label is None and not row.auto_height)
            for k in rows
        )
        if not (fixed and plain):
            super()._update_dimensions(rows)
            return
        width = sum(c.get_render_width(self) for c in self.columns.values())
        header = self.header_height if self.show_header else 0
        # private: the labels' width and the rows' total height, which DataTable keeps
        self.virtual_size = Size(
            width + self._row_label_column_width, self._total_row_height + header
        )

    def _render_line(self, y: int, x1: int, x2: int, base_style: Style) -> Strip:
        """A line of the table, kept by what it shows: the row's cells, whether the cursor
        or the mouse is on it, and the table's geometry (DataTable draws every line again
        after any update, in this private method of its line API)."""
        rows = self.ordered_rows  # brings the rows' heights up to date
        if self.cursor_type != "row" or self.fixed_columns or self._labelled or not self._uniform:
            return super()._render_line(y, x1, x2, base_style)
        header = self.header_height if self.show_header else 0
        columns = self.ordered_columns
        if y < header:
            row_index, line = -1, y
            shown: tuple[object, ...] = tuple(c.label.markup for c in columns)
        elif y - header < len(rows):
            row_index, line = y - header, 0
            shown = tuple(self.get_row(rows[row_index].key))
        else:
            return super()._render_line(y, x1, x2, base_style)
        key = (
            row_index, line, shown, tuple(c.get_render_width(self) for c in columns),
            self.size.width, x1, x2, base_style,
            self.cursor_coordinate.row == row_index, self.hover_coordinate.row == row_index,
            # private: whether the mouse's row is drawn, and the focus and hover state
            self.show_cursor, self._show_hover_cursor, self._pseudo_class_state,
            self.zebra_stripes, self.fixed_rows, self.cell_padding, header,
        )  # fmt: skip
        strip = self._plain_lines.get(key)
        if strip is None:
            strip = self._plain_lines[key] = super()._render_line(y, x1, x2, base_style)
        return strip

    def _render_cell(
        self,
        row_index: int,
        column_index: int,
        base_style: Style,
        width: int,
        cursor: bool = False,
        hover: bool = False,
    ) -> list[list[Segment]]:
        """A cell as one segment, kept by what it shows (DataTable lays it out with Rich, in
        this private method, again after any update)."""
        columns = self.ordered_columns
        if column_index < 0 or (row_index >= 0 and row_index < self.fixed_rows):
            return super()._render_cell(row_index, column_index, base_style, width, cursor, hover)
        if column_index >= len(columns):
            return super()._render_cell(row_index, column_index, base_style, width, cursor, hover)
        column_key = columns[column_index].key
        if row_index == -1:
            label = self.columns[column_key].label
            if label.spans or self.header_height != 1:
                return super()._render_cell(
                    row_index, column_index, base_style, width, cursor, hover
                )
            text: object = label.plain
        else:
            rows = self.ordered_rows
            row = rows[row_index] if 0 <= row_index < len(rows) else None
            try:
                text = None if row is None else self.get_cell(row.key, column_key)
            except CellDoesNotExist:
                text = None
            if row is None or row.height != 1 or not isinstance(text, str) or "\n" in text:
                return super()._render_cell(
                    row_index, column_index, base_style, width, cursor, hover
                )
        key = (
            text, width, row_index, column_index, base_style, cursor, hover,
            # private: whether the mouse's row is drawn, and the focus and hover state
            self.show_cursor, self._show_hover_cursor, self._pseudo_class_state,
            self.cursor_foreground_priority, self.cursor_background_priority, self.cell_padding,
        )  # fmt: skip
        lines = self._plain_cells.get(key)
        if lines is None:
            # private: DataTable's styles of a cell (the cursor's, the header's), as it draws them
            component, post = self._get_styles_to_render_cell(
                row_index == -1, False, False, hover, cursor, self.show_cursor,
                self._show_hover_cursor, self.cursor_foreground_priority == "css",
                self.cursor_background_priority == "css",
            )  # fmt: skip
            meta = Style.from_meta({"row": row_index, "column": column_index})
            style = base_style + meta + component + post
            pad = self.cell_padding
            body = " " * pad + set_cell_size(str(text), max(0, width - 2 * pad)) + " " * pad
            lines = [[Segment(body, style)]]
            self._plain_cells[key] = lines
        return lines
