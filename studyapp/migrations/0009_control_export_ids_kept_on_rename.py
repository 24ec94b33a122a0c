# A control's export id (the name of its files in exports and submissions) is stored when
# it is created, so that renaming it keeps its files matched; existing controls get the id
# they were exported under until now.

import re

from django.db import migrations, models

SAFE_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]{0,99}")


def keep_current_ids(apps, schema_editor):
    ControlSignal = apps.get_model("studyapp", "ControlSignal")
    for control in ControlSignal.objects.all():
        if SAFE_ID.fullmatch(control.name):
            ControlSignal.objects.filter(pk=control.pk).update(export_id=control.name)


class Migration(migrations.Migration):

    dependencies = [
        ('studyapp', '0008_natural_source_of_held_out_controls'),
    ]

    operations = [
        migrations.AddField(
            model_name='controlsignal',
            name='export_id',
            field=models.CharField(blank=True, editable=False, max_length=100),
        ),
        migrations.RunPython(keep_current_ids, migrations.RunPython.noop),
    ]
