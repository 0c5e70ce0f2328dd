"""The plant node's outputs: its publishers and how a session's block, sample or pairs become messages.

`PlantOutputs` creates the plant's publishers from the contract (nodes/interfaces.py) and fills
reused messages: a PlantBlock as RigStateBlock, a PlantSample as RigState (serialized by hand,
app/interface/cdr.StampedEncoder: a third of a message object's cost) and the scalar Float64 topics,
flow_progress, /clock, and in shadow mode the pairs of app.plant.shadow as ShadowBlock. When to publish
(stamps, pacing, who listens) is the plant node's (nodes/plant.py); this module only says how.
"""

from __future__ import annotations

from rclpy.node import Node
from rclpy.publisher import Publisher
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64

from lubrig_interfaces.msg import FlowProgress, RigState, RigStateBlock, ShadowBlock

from ..app.interface import cdr
from ..app.plant.output import check_state_fields
from ..app.plant.session import PlantBlock, PlantSample
from ..app.plant.shadow import ShadowSamples
from . import common
from .interfaces import create_publisher

#: The scalar Float64 topics (scalar_topics), in the order of `PlantOutputs.scalars`.
SCALAR_TOPICS = ("displacement", "velocity", "friction_coefficient")


class PlantOutputs:
    """The plant's publishers and reused messages (see the module docstring)."""

    def __init__(
        self,
        node: Node,
        participant: str,
        *,
        per_sample_state: bool,
        scalar_topics: bool,
        publish_clock: bool,
        shadow: bool,
    ) -> None:
        self.block = create_publisher(node, "state_block")
        self.progress = create_publisher(node, "flow_progress")
        self.state: Publisher | None = create_publisher(node, "state") if per_sample_state else None
        self.scalars = tuple(create_publisher(node, n) for n in SCALAR_TOPICS) if scalar_topics else ()
        self.clock: Publisher | None = create_publisher(node, "/clock") if publish_clock else None
        self.diagnostics = create_publisher(node, "/diagnostics")
        self.config = create_publisher(node, "run_config")
        self.complete = create_publisher(node, "run_complete")
        self.shadow: Publisher | None = create_publisher(node, "shadow_block") if shadow else None
        # RigState serialized by hand (layout from the interface)
        self._state_encoder = cdr.StampedEncoder(RigState.get_fields_and_field_types())
        check_state_fields(self._state_encoder.names)  # encode() takes (index, segment, *values)
        self.state_payload: bytes | None = None  # the newest RigState published
        self._block_msg = RigStateBlock()
        self._progress_msg = FlowProgress()
        self._progress_msg.participant = participant
        self._scalar_msgs = (Float64(), Float64(), Float64())
        self._clock_msg = Clock()
        self._shadow_msg = ShadowBlock()

    def blocks(self) -> list[Publisher]:
        """The block outputs every recording holds: state_block, and shadow_block in shadow mode.

        Wall-clock modes wait for the recorder on these (its per-sample streams are not recorded).
        """
        return [self.block] if self.shadow is None else [self.block, self.shadow]

    def recorded(self) -> list[Publisher]:
        """The outputs a recording must hold (stepped modes wait for the recorder on these)."""
        outputs = [*self.blocks(), *self.scalars]  # state is for rig software, not recorded
        if self.clock is not None:
            outputs.append(self.clock)
        return outputs

    def owned(self) -> list[Publisher]:
        """The outputs no other rig in the namespace may publish (nodes/graph.NamespaceGuard)."""
        outputs = [self.block, self.state, self.config, self.complete, *self.scalars, self.shadow]
        return [p for p in outputs if p is not None]

    def publish_block(self, block: PlantBlock, stamp: tuple[int, int]) -> None:
        """One RigStateBlock of `block`, header stamp (sec, nanosec)."""
        msg = self._block_msg
        msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
        msg.sample_period = block.sample_period
        msg.first_sample_index = block.first_sample_index
        msg.segment = block.segment
        for name, column in block.columns.items():
            setattr(msg, name, common.doubles(column))
        msg.lateness = common.doubles(block.lateness)
        msg.skipped = block.skipped
        self.block.publish(msg)

    def publish_progress(self, stamp: tuple[int, int], segment: int, samples: int) -> None:
        """flow_progress: `samples` of `segment` published."""
        msg = self._progress_msg
        msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
        msg.segment = segment
        msg.samples = samples
        self.progress.publish(msg)

    def publish_clock(self, stamp: tuple[int, int]) -> None:
        """/clock at `stamp` (publish_clock only)."""
        if self.clock is not None:
            self._clock_msg.clock.sec, self._clock_msg.clock.nanosec = stamp
            self.clock.publish(self._clock_msg)

    def publish_scalars(self, s: PlantSample) -> None:
        """displacement, velocity, friction_coefficient of one sample (scalar_topics)."""
        mx, mv, mmu = self._scalar_msgs
        mx.data, mv.data, mmu.data = s.displacement, s.velocity, s.friction_coefficient
        for pub, m in zip(self.scalars, self._scalar_msgs, strict=True):
            pub.publish(m)

    def publish_state(self, stamp: tuple[int, int], s: PlantSample) -> None:
        """One RigState (state_per_sample); kept as `state_payload` for a lockstep resend."""
        if self.state is None:
            return
        payload = self._state_encoder.encode(*stamp, (s.sample_index, s.segment, *s.values))
        self.state.publish(payload)
        self.state_payload = payload

    def publish_shadow(self, pairs: ShadowSamples, stamp: tuple[int, int], sample_period: float) -> None:
        """One ShadowBlock of the pairs (shadow only)."""
        if self.shadow is None:
            return
        msg = self._shadow_msg
        msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
        msg.sample_period = sample_period
        msg.segment = pairs.segment
        msg.sample_index = pairs.sample_index.astype("uint64").tolist()
        msg.measured_displacement = common.doubles(pairs.measured)
        msg.simulated_displacement = common.doubles(pairs.simulated)
        msg.band_velocity = common.doubles(pairs.band_velocity)
        msg.residual = common.doubles(pairs.residual)
        msg.residual_rms = common.doubles(pairs.residual_rms)
        msg.measured_rejected = pairs.rejected
        msg.unpaired = pairs.unpaired
        self.shadow.publish(msg)
