"""Train-to-train and wayside radio ranging: codes, time of arrival, transponders, wayside fusion."""
