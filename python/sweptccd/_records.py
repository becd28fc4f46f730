"""The result records of SPEC sections 7 and 8 as dataclasses.

Each record is built by the C++ core as the very JSON object `sweptccd query`
or `sweptccd world` writes (one place for the record rules); `from_json`
maps it onto these classes field by field. A field a record does not carry
(`error` of an answered pair, `s_lo` of a free one, `links` without
per-link mode) is None; fields SPEC does not name (`elapsed_us`, `stats`, and
any later addition) are kept in `extra`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, fields
from typing import Any, Dict, List, Optional, Tuple

Vec3 = Tuple[float, float, float]


def _vec(v: Any) -> Vec3:
    return (float(v[0]), float(v[1]), float(v[2]))


@dataclass(frozen=True)
class Contact:
    """A witness against the static environment (SPEC 6)."""

    link: int
    object: int
    triangle: int
    s: float
    point_link: Vec3
    point_env: Vec3
    normal: Vec3
    separation: float


@dataclass(frozen=True)
class OtherContact:
    """A witness against another entity (SPEC 8): other_link for an avatar,
    triangle for a tracked object."""

    link: int
    s: float
    point_link: Vec3
    point_other: Vec3
    normal: Vec3
    separation: float
    other_link: Optional[int] = None
    triangle: Optional[int] = None


@dataclass(frozen=True)
class LinkBracket:
    """One link's bracket in per-link mode."""

    link: int
    s_lo: float
    s_hi: float
    t_lo: float
    t_hi: float
    initially_colliding: bool
    undecided: bool
    contact: Optional[Contact] = None


@dataclass(frozen=True)
class OtherLinkBracket:
    """One link's bracket against another entity in per-link mode."""

    link: int
    s_lo: float
    s_hi: float
    t_lo: float
    t_hi: float
    initially_colliding: bool
    undecided: bool
    contact: Optional[OtherContact] = None


@dataclass(frozen=True)
class Other:
    """One entry of a shared-world record's `others` (SPEC 8)."""

    entity: str
    kind: str  # "avatar" or "object"
    window: Tuple[float, float]
    result: str  # "free" or "contact"
    initially_colliding: bool
    undecided: bool
    s_lo: Optional[float] = None
    s_hi: Optional[float] = None
    t_lo: Optional[float] = None
    t_hi: Optional[float] = None
    contacts: Optional[List[OtherContact]] = None
    links: Optional[List[OtherLinkBracket]] = None
    extra: Dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Record:
    """One pair of a pose stream (SPEC 7); `avatar` and `others` are set in
    a shared world's records (SPEC 8)."""

    pair: int
    result: str  # "free", "contact" or "invalid"
    utime0: Optional[int] = None
    utime1: Optional[int] = None
    error: Optional[str] = None
    initially_colliding: Optional[bool] = None
    undecided: Optional[bool] = None
    s_lo: Optional[float] = None
    s_hi: Optional[float] = None
    t_lo: Optional[float] = None
    t_hi: Optional[float] = None
    contacts: Optional[List[Contact]] = None
    links: Optional[List[LinkBracket]] = None
    avatar: Optional[str] = None
    others: Optional[List[Other]] = None
    extra: Dict[str, Any] = field(default_factory=dict)

    @property
    def contact(self) -> bool:
        return self.result == "contact"

    @staticmethod
    def from_json(text: str) -> "Record":
        """The record of one JSON line as `sweptccd query` or `world` writes it."""
        return _record(json.loads(text))


def _split(cls: Any, d: Dict[str, Any]) -> Tuple[Dict[str, Any], Dict[str, Any]]:
    names = {f.name for f in fields(cls)} - {"extra"}
    return ({k: v for k, v in d.items() if k in names},
            {k: v for k, v in d.items() if k not in names})


def _contact(d: Dict[str, Any]) -> Contact:
    return Contact(link=d["link"], object=d["object"], triangle=d["triangle"], s=d["s"],
                   point_link=_vec(d["point_link"]), point_env=_vec(d["point_env"]),
                   normal=_vec(d["normal"]), separation=d["separation"])


def _other_contact(d: Dict[str, Any]) -> OtherContact:
    return OtherContact(link=d["link"], s=d["s"], point_link=_vec(d["point_link"]),
                        point_other=_vec(d["point_other"]), normal=_vec(d["normal"]),
                        separation=d["separation"], other_link=d.get("other_link"),
                        triangle=d.get("triangle"))


def _bracket(d: Dict[str, Any]) -> LinkBracket:
    known, _ = _split(LinkBracket, d)
    c = known.pop("contact", None)
    return LinkBracket(**known, contact=_contact(c) if c is not None else None)


def _other_bracket(d: Dict[str, Any]) -> OtherLinkBracket:
    known, _ = _split(OtherLinkBracket, d)
    c = known.pop("contact", None)
    return OtherLinkBracket(**known, contact=_other_contact(c) if c is not None else None)


def _other(d: Dict[str, Any]) -> Other:
    known, extra = _split(Other, d)
    known["window"] = (known["window"][0], known["window"][1])
    if "contacts" in known:
        known["contacts"] = [_other_contact(c) for c in known["contacts"]]
    if "links" in known:
        known["links"] = [_other_bracket(b) for b in known["links"]]
    return Other(**known, extra=extra)


def _record(d: Dict[str, Any]) -> Record:
    known, extra = _split(Record, d)
    if "contacts" in known:
        known["contacts"] = [_contact(c) for c in known["contacts"]]
    if "links" in known:
        known["links"] = [_bracket(b) for b in known["links"]]
    if "others" in known:
        known["others"] = [_other(o) for o in known["others"]]
    return Record(**known, extra=extra)
