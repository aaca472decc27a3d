"""deckpose: ship-deck attitude and position from monocular images of deck beacons.

Stages (subpackages): :mod:`deckpose.render`, :mod:`deckpose.detect`,
:mod:`deckpose.estimate`, :mod:`deckpose.evaluate`. The records they exchange
live in :mod:`deckpose.records`; conventions in :mod:`deckpose.rotation`,
:mod:`deckpose.pose` and :mod:`deckpose.camera`.
"""

__version__ = "0.1.0"
