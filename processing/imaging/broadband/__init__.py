"""Broadband time-domain imaging: energyscapes by DAS, DAS-CF and DMAS(-CF)."""
