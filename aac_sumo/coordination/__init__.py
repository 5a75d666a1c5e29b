"""Coordinators decide, each control period, which robots plan and what every robot applies."""
