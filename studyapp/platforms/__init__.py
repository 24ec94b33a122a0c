"""The crowd platforms a study pays its participants through (Prolific, MTurk):

    rules.py        what each platform's published rules let a researcher do with a submission
    credentials.py  the researcher's API token, kept encrypted in their login session only
    calls.py        one request to a platform's API, exactly as it will be sent
    prolific.py     Prolific's API over HTTPS
    json_exchange.py  one HTTP(S) request and its answer, believed only as far as it shows
    mturk.py        MTurk's API through boto3 (its sandbox unless asked otherwise)
    actions.py      the requests for a study's participants: planned (the dry run), sent
                    once each, and logged
"""
