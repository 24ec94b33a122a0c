# Appropriateness studies: a design name of 15 characters, and the mismatched clip's shown control.

import django.db.models.deletion
import studyapp.designs.registry
from django.db import migrations, models


class Migration(migrations.Migration):

    dependencies = [
        ('studyapp', '0011_question_order'),
    ]

    operations = [
        migrations.AddField(
            model_name='stimulus',
            name='shown_control',
            field=models.ForeignKey(blank=True, help_text='appropriateness: the control a page shows this clip of another control against (empty: its own)', null=True, on_delete=django.db.models.deletion.CASCADE, related_name='mismatched_stimuli', to='studyapp.controlsignal'),
        ),
        migrations.AlterField(
            model_name='study',
            name='design',
            field=models.CharField(choices=studyapp.designs.registry.choices, default='single', max_length=20),
        ),
        migrations.AlterField(
            model_name='study',
            name='pages_per_participant',
            field=models.PositiveSmallIntegerField(default=8, help_text='side-by-side, pairwise and appropriateness: pages each participant answers, attention and instructed checks included'),
        ),
    ]
