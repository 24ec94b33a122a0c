# The study's steps tick "Preview" once the researcher has seen the preview.

from django.db import migrations, models


class Migration(migrations.Migration):

    dependencies = [
        ('studyapp', '0009_control_export_ids_kept_on_rename'),
    ]

    operations = [
        migrations.AddField(
            model_name='study',
            name='previewed_at',
            field=models.DateTimeField(blank=True, help_text='when the researcher last saw the preview', null=True),
        ),
    ]
