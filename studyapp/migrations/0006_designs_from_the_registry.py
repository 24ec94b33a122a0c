# The design field's choices come from the designs' registry, and the page counts include instructed checks.

import studyapp.designs.registry
from django.db import migrations, models


class Migration(migrations.Migration):

    dependencies = [
        ('studyapp', '0005_study_updated_and_shown_at'),
    ]

    operations = [
        migrations.AlterField(
            model_name='study',
            name='clips_per_participant',
            field=models.PositiveSmallIntegerField(default=20, help_text='single design: clips each participant rates, attention and instructed checks included'),
        ),
        migrations.AlterField(
            model_name='study',
            name='design',
            field=models.CharField(choices=studyapp.designs.registry.choices, default='single', max_length=12),
        ),
        migrations.AlterField(
            model_name='study',
            name='instructed_checks',
            field=models.PositiveSmallIntegerField(default=0, help_text='pages per participant, among their pages, that tell them which answer to give (not analysed)'),
        ),
        migrations.AlterField(
            model_name='study',
            name='pages_per_participant',
            field=models.PositiveSmallIntegerField(default=8, help_text='side-by-side and pairwise: pages each participant answers, attention and instructed checks included'),
        ),
    ]
