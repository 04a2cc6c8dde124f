"""Analysis (pure): simulation against tracking, the campaign, the paper's figures."""
