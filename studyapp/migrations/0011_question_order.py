# Questions are asked in an order the researcher sets (each part on its own).

from django.db import migrations, models


class Migration(migrations.Migration):

    dependencies = [
        ('studyapp', '0010_study_previewed_at'),
    ]

    operations = [
        migrations.AlterModelOptions(
            name='question',
            options={'ordering': ['study', 'part', 'order', 'created', 'pk']},
        ),
        migrations.AddField(
            model_name='question',
            name='order',
            field=models.PositiveSmallIntegerField(default=0, help_text='its place among the questions of its part'),
        ),
    ]
