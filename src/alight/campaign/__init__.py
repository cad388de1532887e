"""Campaigns: many missions over a grid of conditions, presets and seeds, and their report.

    from alight.campaign import load_campaign, run_campaign
    result = run_campaign("examples/campaigns/smoke.yaml", "runs/smoke", workers=2)

See docs/campaigns.md for the campaign file and the output directory.
"""

from alight.campaign.run import CampaignInterrupted, CampaignRunResult, run_campaign
from alight.campaign.spec import Campaign, PlannedMission, campaign_from_dict, load_campaign
from alight.campaign.summary import wilson95, write_summary

__all__ = [
    "Campaign",
    "CampaignInterrupted",
    "CampaignRunResult",
    "PlannedMission",
    "campaign_from_dict",
    "load_campaign",
    "run_campaign",
    "wilson95",
    "write_summary",
]
