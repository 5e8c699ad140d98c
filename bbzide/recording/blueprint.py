"""The layout the Rerun viewer opens a bbzide recording with (a Rerun blueprint).

Design: one screen that answers "where are the robots, what are they doing, how is their
memory": the world in 3D (robots coloured by LED, headings, radio links, targets) on the left;
on the right, heap use per robot, radio traffic, and the event log (errors, role changes,
targets found). The blueprint is written into the `.rrd` itself (`RecordingStream.save(...,
default_blueprint=...)`), so `rerun mission.rrd` needs no extra file.
"""

from __future__ import annotations

from typing import Any

from bbzide.recording import layout


def mission_blueprint() -> Any:
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(name="World", origin="/world"),
            rrb.Vertical(
                rrb.TimeSeriesView(name="Heap used (bytes, per robot)",
                                   origin=f"{layout.HEAP}/used"),
                rrb.TimeSeriesView(name="Radio (sent, received, dropped, bytes)",
                                   origin=layout.MESSAGE_TOTALS),
                rrb.TextLogView(name="Events", origin=layout.EVENTS),
            ),
            column_shares=[3, 2],
        ),
        rrb.SelectionPanel(state="collapsed"),
    )
