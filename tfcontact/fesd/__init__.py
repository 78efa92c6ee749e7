"""tfcontact.fesd"""
