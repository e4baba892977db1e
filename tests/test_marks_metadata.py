"""Marks.metadata_for keeps the changes made so far folded (a change before each descent made
it overlay the whole day's on every impulse): the metadata in force must be the same whatever
the order of the calls and of the changes."""

from __future__ import annotations

from station.session.marks import Marks
from station.session.records import Metadata, MetadataAnnotation


def change(from_descent: int, **values: object) -> MetadataAnnotation:
    return MetadataAnnotation(Metadata.from_values(values), from_descent=from_descent)


def test_changes_from_earlier_descents_after_later_ones() -> None:
    marks = Marks(Metadata.from_values({"ski": "base", "wax": "none"}))
    assert marks.metadata_for(3).ski == "base"
    marks.note(change(1, ski="A"))
    assert (marks.metadata_for(1).ski, marks.metadata_for(9).ski) == ("A", "A")
    marks.note(change(5, ski="B"))  # from descent 5 on
    marks.note(change(2, wax="W1"))  # from 2 on, entered after the change from 5
    got = [(marks.metadata_for(n).ski, marks.metadata_for(n).wax) for n in (0, 1, 2, 4, 5, 9)]
    assert got == [
        ("base", "none"), ("A", "none"), ("A", "W1"), ("A", "W1"), ("B", "W1"), ("B", "W1")
    ]  # fmt: skip
    marks.note(change(3, ski="C"))  # made last: in force from 3 on, over the change from 5
    assert [marks.metadata_for(n).ski for n in (2, 3, 5, 9)] == ["A", "C", "C", "C"]
    marks.note(MetadataAnnotation(Metadata.from_values({"ski": "D"}), descents=(4,)))
    assert [marks.metadata_for(n).ski for n in (3, 4, 5)] == ["C", "D", "C"]


def test_a_change_before_each_descent() -> None:
    marks = Marks(Metadata.from_values({}))
    for n in range(1, 200):
        marks.note(change(n, ski="A" if n % 2 else "B"))
        assert marks.metadata_for(n).ski == ("A" if n % 2 else "B")
        assert marks.metadata_for(n + 1).ski == ("A" if n % 2 else "B")
    assert marks.metadata_for(10).ski == "B" and marks.metadata_for(0).ski is None
