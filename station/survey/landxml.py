"""Reader for LandXML 1.2 survey files: ``CgPoints`` and ``Survey``'s raw observations.

Office software (and many field controllers) exports LandXML. Read here:

- ``Units/Metric`` or ``Units/Imperial``: ``linearUnit`` (meter, foot, USSurveyFoot, …) and
  ``angularUnit`` (radians, grads, decimal degrees, decimal dd.mm.ss).
- ``CgPoints/CgPoint``: ``name`` and the text ``northing easting [elevation]`` (LandXML's
  coordinate order), or ``pntRef`` to another CgPoint: points given by coordinates.
- ``Survey/InstrumentSetup``: ``id``, ``stationName``, ``instrumentHeight``; its
  ``InstrumentPoint`` (coordinates or ``pntRef``) places it; a ``Backsight`` with ``circle``
  and a ``BacksightPoint`` of known coordinates orients it (ω = azimuth − circle).
- ``RawObservation`` (anywhere under ``Survey``): ``setupID`` (or its enclosing setup),
  ``horizAngle``, ``zenithAngle``, ``slopeDistance`` (or ``horizDistance``), ``targetHeight``,
  and a ``TargetPoint`` naming the point (``name`` or ``pntRef``).

XML is parsed with defusedxml: a file with entity declarations (the "billion laughs" bomb) or
external references is refused, never expanded.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET  # noqa: S405 - only the Element type; parsing is defusedxml
from dataclasses import replace

import defusedxml.ElementTree as DET  # type: ignore[import-untyped]
from defusedxml import DefusedXmlException

from station.errors import InputError
from station.survey.polar import KnownPoint, Observation, ObservationSet, Setup, read_number
from station.survey.topcon import packed_dms

LINEAR = {
    "meter": 1.0,
    "metre": 1.0,
    "millimeter": 1e-3,
    "centimeter": 1e-2,
    "kilometer": 1e3,
    "foot": 0.3048,
    "intlfoot": 0.3048,
    "ussurveyfoot": 1200.0 / 3937.0,
}
ANGULAR = {
    "radians": "rad",
    "grads": "gon",
    "gon": "gon",
    "decimal degrees": "deg",
    "degrees": "deg",
    "decimal dd.mm.ss": "dms",
}


class _LineTreeBuilder(ET.TreeBuilder):
    """A tree builder that notes each element's line, so an error names where it stands."""

    def __init__(self) -> None:
        super().__init__()
        self.parser: DET.DefusedXMLParser | None = None
        self.lines: dict[int, int] = {}

    def start(self, tag, attrs):
        elem = super().start(tag, attrs)
        if self.parser is not None:
            self.lines[id(elem)] = self.parser.parser.CurrentLineNumber
        return elem


def _parse(text: str, path: str) -> tuple[ET.Element, dict[int, int]]:
    builder = _LineTreeBuilder()
    parser = DET.DefusedXMLParser(target=builder, forbid_dtd=True)
    builder.parser = parser
    try:
        parser.feed(text.encode("utf-8"))
        root = parser.close()
    except DefusedXmlException as exc:
        raise InputError(
            f"XML with a DTD or entities is refused ({type(exc).__name__})", path=path
        ) from None
    except ET.ParseError as exc:
        line = exc.position[0] if getattr(exc, "position", None) else None
        raise InputError(f"not well-formed XML: {exc}", path=path, line=line) from None
    except LookupError as exc:  # the XML declaration names an encoding Python does not know
        raise InputError(f"XML in an unknown encoding: {exc}", path=path, line=1) from None
    return root, builder.lines


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _find_all(root: ET.Element, name: str) -> list[ET.Element]:
    return [e for e in root.iter() if _local(e.tag) == name]


class _Reader:
    def __init__(self, root: ET.Element, path: str, lines: dict[int, int]):
        self.root, self.path, self.lines = root, path, lines
        self.out = ObservationSet(format="LandXML")
        self.metres, self.angular = 1.0, "deg"
        self.points: dict[str, tuple[float, float, float]] = {}

    def where(self, elem: ET.Element, attr: str) -> tuple[int | None, str]:
        """The line and field an error about ``elem``'s attribute ``attr`` names."""
        ident = elem.get("id") or elem.get("name") or ""
        return self.lines.get(id(elem)), f"{_local(elem.tag)}{' ' + ident if ident else ''} {attr}"

    def error(self, msg: str, elem: ET.Element, attr: str) -> InputError:
        line, field = self.where(elem, attr)
        return InputError(msg, path=self.path, line=line, field=field)

    def num(self, elem: ET.Element, attr: str) -> float | None:
        raw = elem.get(attr)
        if raw is None or not raw.strip():
            return None
        return read_number(raw, self.path, *self.where(elem, attr))

    def angle(self, elem: ET.Element, attr: str) -> float | None:
        raw = elem.get(attr)
        if raw is None or not raw.strip():
            return None
        try:
            if self.angular == "dms":
                return packed_dms(raw)
            v = float(raw)
        except ValueError as exc:
            raise self.error(str(exc), elem, attr) from None
        return {"rad": v, "gon": v * math.pi / 200.0, "deg": math.radians(v)}[self.angular]

    def units(self) -> None:
        for tag in ("Metric", "Imperial"):
            for u in _find_all(self.root, tag):
                lin = (u.get("linearUnit") or "meter").strip().lower()
                ang = (u.get("angularUnit") or "decimal degrees").strip().lower()
                if lin not in LINEAR:
                    raise self.error(f"unknown linear unit {lin!r}", u, "linearUnit")
                if ang not in ANGULAR:
                    raise self.error(f"unknown angular unit {ang!r}", u, "angularUnit")
                self.metres, self.angular = LINEAR[lin], ANGULAR[ang]
                return

    def coords(self, elem: ET.Element) -> tuple[float, float, float] | None:
        ref = elem.get("pntRef")
        if ref and ref in self.points:
            return self.points[ref]
        parts = (elem.text or "").split()
        if len(parts) < 2:
            return None
        try:
            vals = [float(p) * self.metres for p in parts[:3]]
        except ValueError:
            raise self.error(
                f"{elem.text!r} is not 'northing easting elevation'", elem, "coordinates"
            ) from None
        if not all(math.isfinite(v) for v in vals):
            raise self.error("coordinates are not finite", elem, "coordinates")
        n, e = vals[0], vals[1]
        return e, n, vals[2] if len(vals) > 2 else 0.0

    def cg_points(self) -> None:
        for cg in _find_all(self.root, "CgPoint"):
            name = cg.get("name") or cg.get("oID") or ""
            enh = self.coords(cg)
            if name and enh is not None:
                self.points[name] = enh
                self.out.known.append(KnownPoint(name, *enh))

    def setups(self) -> dict[str, Setup]:
        found: dict[str, Setup] = {}
        for s in _find_all(self.root, "InstrumentSetup"):
            name = s.get("stationName") or s.get("id") or ""
            enh = None
            for ip in (e for e in s if _local(e.tag) == "InstrumentPoint"):
                enh = self.coords(ip)
                name = s.get("stationName") or ip.get("pntRef") or name
            e, n, h = enh or (0.0, 0.0, 0.0)
            hi = (self.num(s, "instrumentHeight") or 0.0) * self.metres
            setup = Setup(name, e, n, h, hi, known=enh is not None, oriented=False)
            setup = self.orient(s, setup)
            found[s.get("id") or name] = setup
            self.out.setups.append(setup)
        return found

    def orient(self, elem: ET.Element, setup: Setup) -> Setup:
        for bs in (e for e in elem if _local(e.tag) == "Backsight"):
            circle = self.angle(bs, "circle") or 0.0
            az = self.angle(bs, "azimuth")
            point = next((e for e in bs if _local(e.tag) == "BacksightPoint"), None)
            target = self.coords(point) if point is not None else None
            if az is None and target is not None and setup.known:
                az = math.atan2(target[0] - setup.e, target[1] - setup.n)
            if az is not None:
                return replace(setup, orientation=az - circle, oriented=True)
        return setup

    def observations(self, setups: dict[str, Setup]) -> None:
        for parent in _find_all(self.root, "InstrumentSetup") + _find_all(
            self.root, "ObservationGroup"
        ):
            for ob in (e for e in parent if _local(e.tag) == "RawObservation"):
                self.observation(ob, parent, setups)

    def observation(self, ob: ET.Element, parent: ET.Element, setups: dict[str, Setup]) -> None:
        key = ob.get("setupID") or parent.get("setupID") or parent.get("id") or ""
        setup = setups.get(key)
        if setup is None:
            raise self.error(f"no InstrumentSetup with id {key!r}", ob, "setupID")
        tp = next((e for e in ob if _local(e.tag) == "TargetPoint"), None)
        name = "" if tp is None else (tp.get("name") or tp.get("pntRef") or "")
        hz, zen = self.angle(ob, "horizAngle"), self.angle(ob, "zenithAngle")
        sd, hd = self.num(ob, "slopeDistance"), self.num(ob, "horizDistance")
        if hz is None or (sd is None and hd is None):
            self.out.unreduced.setdefault(name, 0)
            return
        self.out.observations.append(
            Observation(
                point=name,
                hz=hz,
                zenith=zen if zen is not None else math.pi / 2,
                slope_distance=None if sd is None else sd * self.metres,
                horizontal_distance=None if hd is None else hd * self.metres,
                reflector_height=(self.num(ob, "targetHeight") or 0.0) * self.metres,
                setup=setup,
            )
        )


def parse_landxml(text: str, path: str = "<landxml>") -> ObservationSet:
    """Read a LandXML 1.2 file; entity declarations are refused, damaged values named."""
    root, lines = _parse(text, path)
    reader = _Reader(root, path, lines)
    reader.units()
    reader.cg_points()
    reader.observations(reader.setups())
    out = reader.out
    if out.unreduced:
        n = len(out.unreduced)
        out.warnings.append(
            f"{n} observation{'s' * (n != 1)} without an angle and a distance "
            f"not reduced: {', '.join(list(out.unreduced)[:8])}"
        )
    return out
