"""The descents table: Textual's DataTable, with cells drawn without Rich's layout.

A DataTable forgets every cell it has drawn whenever a row is added or a cell changes (its
caches are keyed by a count of updates), and draws each again through Rich's console (markup,
padding, wrapping): ~1 ms a cell, 20 rows × 11 columns after every descent, most of the UI's
time from a descent's last impulse to its row on the screen. The station's cells are one line
of plain text each, already justified (``app.cell``): drawn here as one segment cropped or
padded to the column's width, and kept by what they show, so a new descent draws its own row
and reuses the others. The segments are those Rich made (the line is simplified into the same
strip), and text in a cell is text: a note "[kg]" is not taken for markup.
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
from textual.widgets.data_table import Row, RowKey


class ResultsTable(DataTable[str]):
    """A DataTable whose cells are single lines of plain text (``str``)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        # set first: DataTable's own __init__ clears the caches
        self._plain_cells: LRUCache[tuple[object, ...], list[list[Segment]]] = LRUCache(4000)
        self._plain_lines: LRUCache[tuple[object, ...], Strip] = LRUCache(1000)
        self._reset_order()
        super().__init__(*args, **kwargs)

    def _clear_caches(self) -> None:
        super()._clear_caches()
        self._plain_cells.clear()
        self._plain_lines.clear()
        self._reset_order()

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
        self._order: list[Row] = []
        self._offsets: list[tuple[RowKey, int]] = []
        self._uniform = True  # every row one line high

    @property
    def ordered_rows(self) -> list[Row]:
        """The rows as they are shown. DataTable builds this list (and the row of every line
        of the table) again after every added row or changed cell: 2000 rows looked up for
        each descent near descent 2000. The station's rows are only ever added at the end, so
        the list is extended; a sort, a removal or a clear starts it afresh."""
        order, n = self._order, self.row_count
        if len(order) > n:
            self._reset_order()
            order = self._order
        get_key, rows = self._row_locations.get_key, self.rows
        while len(order) < n:
            key = get_key(len(order))
            assert key is not None, "a row index without its row"
            row = rows[key]
            order.append(row)
            self._uniform = self._uniform and row.height == 1 and not row.auto_height
        return order

    @property
    def _y_offsets(self) -> list[tuple[RowKey, int]]:
        order = self.ordered_rows
        if not self._uniform:
            return [(row.key, y) for row in order for y in range(row.height)]
        offsets = self._offsets
        offsets.extend((row.key, 0) for row in order[len(offsets) :])
        return offsets

    def _get_row_region(self, row_index: int) -> Region:
        """A row's place: its index below the header when every row is one line (DataTable
        adds up the heights of the rows above it)."""
        self.ordered_rows  # noqa: B018 - brings the rows' heights up to date
        if not self._uniform:
            return super()._get_row_region(row_index)
        if not self.is_valid_row_index(row_index):
            return Region(0, 0, 0, 0)
        width = sum(c.get_render_width(self) for c in self.columns.values())
        width += self._row_label_column_width
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
        row, kept for the last 1000 rows: objects every full garbage collection walks). The
        station's columns have fixed widths and its rows one line: nothing to measure."""
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
        self.virtual_size = Size(
            width + self._row_label_column_width, self._total_row_height + header
        )

    def _render_line(self, y: int, x1: int, x2: int, base_style: Style) -> Strip:
        """A line of the table, kept by what it shows: the row's cells, whether the cursor
        or the mouse is on it, and the table's geometry (DataTable draws every line again
        after any update)."""
        if self.cursor_type != "row" or self.fixed_columns or self._labelled_row_exists:
            return super()._render_line(y, x1, x2, base_style)
        try:
            row_key, line = self._get_offsets(y)
        except LookupError:
            return super()._render_line(y, x1, x2, base_style)
        columns = self.ordered_columns
        if row_key is self._header_row_key:
            row_index = -1
            shown: tuple[object, ...] = tuple(c.label.markup for c in columns)
        else:
            found = self._row_locations.get(row_key)
            row_index = -2 if found is None else found
            data = self._data[row_key]
            shown = tuple(data.get(c.key) for c in columns)
        key = (
            row_index, line, shown, tuple(c.get_render_width(self) for c in columns),
            self.size.width, x1, x2, base_style,
            self.cursor_coordinate.row == row_index, self.hover_coordinate.row == row_index,
            self.show_cursor, self._show_hover_cursor, self._pseudo_class_state,
            self.zebra_stripes, self.fixed_rows,
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
        if column_index < 0 or (row_index >= 0 and row_index < self.fixed_rows):
            return super()._render_cell(row_index, column_index, base_style, width, cursor, hover)
        column_key = self._column_locations.get_key(column_index)
        if column_key is None:
            return super()._render_cell(row_index, column_index, base_style, width, cursor, hover)
        if row_index == -1:
            label = self.columns[column_key].label
            if label.spans or self.header_height != 1:
                return super()._render_cell(
                    row_index, column_index, base_style, width, cursor, hover
                )
            text: object = label.plain
        else:
            row_key = self._row_locations.get_key(row_index)
            row = None if row_key is None else self.rows.get(row_key)
            text = None if row_key is None else self._data[row_key].get(column_key)
            if row is None or row.height != 1 or not isinstance(text, str) or "\n" in text:
                return super()._render_cell(
                    row_index, column_index, base_style, width, cursor, hover
                )
        key = (
            text, width, row_index, column_index, base_style, cursor, hover,
            self.show_cursor, self._show_hover_cursor, self._pseudo_class_state,
            self.cursor_foreground_priority, self.cursor_background_priority,
        )  # fmt: skip
        lines = self._plain_cells.get(key)
        if lines is None:
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
