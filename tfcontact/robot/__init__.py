"""tfcontact.robot"""
