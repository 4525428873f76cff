def load_campaign(path):
    raise NotImplementedError


def write_campaign(campaign, directory):
    raise NotImplementedError
