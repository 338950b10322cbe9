"""Planning through contact for a rotating slider (issue 32): sticking face-contact modes relaxed as
sparse moment blocks, non-collision modes in the slider's frame, a layered mode graph, its convex
relaxation (Clarabel) and rounding (SNOPT on sampled paths). See planner.py for the entry point."""

from lerobot_gcs_push.contact.planner import ContactPlanner

__all__ = ["ContactPlanner"]
