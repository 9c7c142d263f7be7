"""This UAV's own contacts (pure): its sightings, grouped by intruder.

The camera reports every intruder under the sensor at 5 Hz. A sighting is the same contact
as an earlier one when it lies within the contact's gate: ``CONTACT_GATE_SIGMAS`` sigma of
the contact's predicted position (its own prediction's uncertainty and one sighting's error
combined), at most ``2 r_s``. A contact's prediction is good to a few metres a fifth of a
second ahead, so two intruders under the sensor at once (a vehicle passing a walker) are two
contacts and two tracks, not one track that averages them. A contact not seen for
``CONTACT_GAP_S`` has passed out of the footprint. Each contact knows the alert it belongs
to (the Agent decides: an open alert expected there, or a new one) and fits its track on top
of that alert's track (:class:`~companion.agent.alerts.track.TrackFit`), so every pass of
every member refines the same track.

Times are vehicle seconds, positions complex north + i east metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from companion.agent.alerts.track import TrackFit
from companion.group.messages import Track

CONTACT_GAP_S = 1.5  # a contact unseen this long has left the footprint (s)
CONTACT_GATE_SIGMAS = 4.0  # a sighting this many sigma from a contact's prediction is another one
TRACK_UPDATE_S = 1.0  # a contact's track is sent at most this often while seen (s)


@dataclass
class Contact:
    """One intruder under (or just out of) this UAV's sensor.

    Attributes:
        fit: its sightings' fit.
        last_t_s: its newest sighting (s).
        first_t_s: its first sighting (s).
        alert_id: the alert it belongs to, None until decided.
        sent_t_s: when its track was last sent (s).
        sent_sightings: how many sightings the track sent held.
    """

    fit: TrackFit
    last_t_s: float
    alert_id: str | None = None
    first_t_s: float = 0.0
    sent_t_s: float = -1e9
    sent_sightings: int = 0

    def track(self) -> Track:
        """Its track now (it has at least one sighting)."""
        tr = self.fit.track()
        assert tr is not None
        return tr

    def unsent(self) -> bool:
        """Whether it holds sightings its last sent track did not."""
        return len(self.fit) > self.sent_sightings


@dataclass
class Contacts:
    """This UAV's contacts.

    Args:
        gate_m: the widest gate (m): a sighting farther than this from a contact's predicted
            position is never the same contact, however uncertain the prediction.
    """

    gate_m: float
    items: list[Contact] = field(default_factory=list)

    def gate(self, track: Track, sighting_sigma_m: float, t_s: float) -> float:
        """How far (m) from a contact's ``track`` predicted to ``t_s`` (s) a sighting is that
        contact: ``CONTACT_GATE_SIGMAS`` sigma of the prediction and one sighting (error
        ``sighting_sigma_m``, m) combined, at most ``gate_m``."""
        sigma = math.hypot(track.sigma_m(t_s), sighting_sigma_m)
        return min(self.gate_m, CONTACT_GATE_SIGMAS * sigma)

    def find(self, t_s: float, pos_m: complex) -> Contact | None:
        """The contact a sighting at ``t_s`` (s) of an intruder at ``pos_m`` (m) belongs to:
        of those whose gate holds it, the nearest in sigma; None if no gate holds it."""
        best, best_z = None, math.inf
        for c in self.items:
            track = c.track()  # one fit per contact and sighting
            g = self.gate(track, c.fit.sighting_sigma_m, t_s)
            d = abs(track.predict(t_s) - pos_m)
            if d <= g and d / g < best_z:
                best, best_z = c, d / g
        return best

    def live_alerts(self, t_s: float) -> set[str]:
        """The alerts of the contacts under the sensor at ``t_s`` (s): seen within
        ``CONTACT_GAP_S``. A new contact beside one of them is another intruder."""
        return {
            c.alert_id
            for c in self.items
            if c.alert_id is not None and t_s - c.last_t_s <= CONTACT_GAP_S
        }

    def open(self, t_s: float, pos_m: complex, prior: Track | None) -> Contact:
        """A new contact of a sighting at ``t_s`` (s) at ``pos_m`` (m), its fit on top of
        ``prior`` (the track of the alert expected there, if any)."""
        c = Contact(TrackFit(prior=prior), t_s, first_t_s=t_s)
        c.fit.add(t_s, pos_m)
        self.items.append(c)
        return c

    @staticmethod
    def see(c: Contact, t_s: float, pos_m: complex) -> None:
        """Another sighting of contact ``c`` at ``t_s`` (s) at ``pos_m`` (m)."""
        c.fit.add(t_s, pos_m)
        c.last_t_s = t_s

    def expire(self, t_s: float) -> list[Contact]:
        """Drop and return the contacts not seen for ``CONTACT_GAP_S`` at ``t_s`` (s)."""
        gone = [c for c in self.items if t_s - c.last_t_s > CONTACT_GAP_S]
        self.items = [c for c in self.items if c not in gone]
        return gone

    def rename(self, old_id: str, new_id: str) -> None:
        """An earlier report of the same intruder replaced alert ``old_id``."""
        for c in self.items:
            if c.alert_id == old_id:
                c.alert_id = new_id
